"""The tests' own compiler runs (C hosts, harnesses, objects), through hammerbit's compile cache.

A test that builds a C host or a harness compiles the same inputs in every run; through
:func:`hammerbit.fmu.compile_cache.compile_output`, which keys on every byte that can change the
output, the second run on gets the output without running the compiler (the cache is checked in
tests/test_compile_cache.py).  ``scratch``: the test's temporary directories named in the command,
whose names change from run to run but not the output."""
from pathlib import Path

from hammerbit.fmu.compile_cache import compile_output


def compile_c(cmd, output, *scratch) -> Path:
    """``output`` made as the compiler command ``cmd`` (which names it after ``-o``) makes it; a
    failing compiler fails the test with its messages."""
    compile_output(cmd, output, scratch=scratch, what="compiling a test's C", error=AssertionError)
    return Path(output)
