"""Python sources parsed once per test process, shared by the checks that read the library's code."""
import ast
from functools import lru_cache


@lru_cache(maxsize=None)
def parse(source: str) -> ast.Module:
    """``ast.parse(source)``, once per process for each text (the architecture checks walk the same
    files many times); callers only read the tree."""
    return ast.parse(source)
