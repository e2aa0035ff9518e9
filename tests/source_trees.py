"""Python sources parsed once per test process, shared by the checks that read the library's code."""
import ast
from functools import lru_cache


@lru_cache(maxsize=None)
def parse(source: str) -> ast.Module:
    """``ast.parse(source)``, once per process for each text (the architecture checks walk the same
    files many times); callers only read the tree."""
    return ast.parse(source)


@lru_cache(maxsize=None)
def nodes(source: str) -> tuple:
    """Every node of :func:`parse`'s tree of ``source``, in :func:`ast.walk`'s order, once per
    process for each text (each check walks every file of the library)."""
    return tuple(ast.walk(parse(source)))
