"""Partial evaluation of a kernel: some of its arguments bound as compile-time constants.

numba folds the free variables of a closure into the compiled code: arrays
become read-only constant data and integers literal types, so branches on
them vanish and loops over them get constant trip counts.  That is what an
IR-inlined call with constant arguments achieves too, but inlining makes numba
re-run its untyped passes and deep-copy the callee's IR into the caller, which
is slow for a function as large as the solver driver.  A bound copy
compiles as one ordinary function, and numba caches it like any other (a
closure's cache entry is keyed on its code and on the values it closes over).

:func:`bind` re-compiles the source of a plain Python function with the named
parameters turned into free variables of an enclosing function.  The copy
keeps the original's file, line numbers and module globals, so tracebacks,
numba's error messages and the cache locator point at the real source.
"""
from __future__ import annotations

import ast
import inspect
import textwrap


def bind(func, name: str, **constants):
    """A copy of ``func`` named ``name`` without the parameters in ``constants``, which it reads
    as constants instead.

    ``func`` is a plain Python function or a numba dispatcher (its ``py_func``
    is used; the decorators are dropped, so decorate the result).  Raises
    ``TypeError`` if a name in ``constants`` is not a positional parameter of ``func``, or if
    ``func`` is itself a closure (the copy sees only the module's globals).
    """
    py = getattr(func, "py_func", func)
    if py.__code__.co_freevars:
        raise TypeError(f"{py.__name__}() is a closure (over {', '.join(py.__code__.co_freevars)}); "
                        f"bind reads only module globals")
    lines, first = inspect.getsourcelines(py)
    fdef = ast.parse(textwrap.dedent("".join(lines))).body[0]
    params = [a.arg for a in fdef.args.args]
    unknown = sorted(set(constants) - set(params))
    if unknown:
        raise TypeError(f"{py.__name__}() has no positional parameter(s) {', '.join(unknown)}")
    fdef.decorator_list = []
    fdef.name = name
    fdef.args.args = [a for a in fdef.args.args if a.arg not in constants]
    outer_name = f"_bound_{name}"
    outer = ast.FunctionDef(
        name=outer_name,
        args=ast.arguments(posonlyargs=[], args=[ast.arg(arg=k) for k in constants], vararg=None,
                           kwonlyargs=[], kw_defaults=[], kwarg=None, defaults=[]),
        body=[fdef, ast.Return(value=ast.Name(id=name, ctx=ast.Load()))],
        decorator_list=[], returns=None, type_comment=None)
    if "type_params" in ast.FunctionDef._fields:  # Python >= 3.12
        outer.type_params = []
    module = ast.Module(body=[outer], type_ignores=[])
    ast.fix_missing_locations(module)
    ast.increment_lineno(module, first - 1)
    scope: dict = {}
    exec(compile(module, inspect.getsourcefile(py), "exec"), py.__globals__, scope)  # noqa: S102
    bound = scope[outer_name](**constants)
    bound.__qualname__ = name
    return bound
