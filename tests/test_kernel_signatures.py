"""Small signatures: no numba kernel of the string side, the co-simulation, the drillstring or the
studies takes, or is called with, more than :data:`MAX_PARAMS` arguments.

Read from the sources with :mod:`ast` (nothing is imported or compiled).  A kernel with a long
argument list groups them into records (named tuples of arrays and scalars, as
:mod:`hammerbit.model.string_step` does for the exchange).  The C entry points (``@cfunc``) are
exempt: their signature is the C ABI the native front's sources call.
"""
from __future__ import annotations

import ast
from pathlib import Path

from source_trees import nodes, parse

ROOT = Path(__file__).resolve().parents[1]
#: most arguments a kernel takes (issue 26: "no kernel call passes more than about 10 arguments")
MAX_PARAMS = 10
#: the modules this check covers (the hammer kernels have their own owner and check)
SCOPE = ("fmu_src/string_*.py", "coupling/cosim/*.py", "coupling/drillstring/*.py", "coupling/studies/*.py",
         "coupling/fmu/native_string*.py")
#: decorators that make a numba kernel (a ``cfunc``'s signature is a C ABI: exempt)
KERNEL_DECORATORS = ("njit", "jit", "generated_jit", "vectorize", "guvectorize")


def _files():
    return sorted({p for pattern in SCOPE for p in ROOT.glob(pattern)})


def _decorator_name(d: ast.expr) -> str:
    if isinstance(d, ast.Call):
        d = d.func
    return d.attr if isinstance(d, ast.Attribute) else getattr(d, "id", "")


def _param_count(f: ast.FunctionDef) -> int:
    a = f.args
    return (len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + (a.vararg is not None)
            + (a.kwarg is not None))


def _kernels() -> dict:
    """{name: (file, line, parameter count)} of every numba kernel in :data:`SCOPE`."""
    out = {}
    for path in _files():
        for node in nodes(path.read_text(encoding="utf-8")):
            if isinstance(node, ast.FunctionDef) and any(
                    _decorator_name(d) in KERNEL_DECORATORS for d in node.decorator_list):
                out[node.name] = (path.relative_to(ROOT), node.lineno, _param_count(node))
    return out


def test_the_check_sees_the_string_kernels():
    k = _kernels()
    for name in ("exchange_step_modal", "exchange_step_dense", "string_step_dense", "held_force"):
        assert name in k, sorted(k)
    assert len(_files()) > 20


def test_no_kernel_takes_more_than_ten_parameters():
    long = {n: v for n, v in _kernels().items() if v[2] > MAX_PARAMS}
    assert not long, f"kernels with more than {MAX_PARAMS} parameters (group them in records): {long}"


def test_no_kernel_is_called_with_more_than_ten_arguments():
    """Every call of one of the kernels, in the library and in the tests: at most ten arguments."""
    names = set(_kernels())
    bad = []
    for path in sorted(ROOT.glob("coupling/**/*.py")) + sorted(ROOT.glob("fmu_src/*.py")):
        for node in nodes(path.read_text(encoding="utf-8")):
            if not isinstance(node, ast.Call):
                continue
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
            if name in names and len(node.args) + len(node.keywords) > MAX_PARAMS:
                bad.append(f"{path.relative_to(ROOT)}:{node.lineno} {name}")
    assert not bad, bad


def test_a_kernel_calls_only_kernels_of_its_own_module():
    """numba's cache entry of a kernel holds its callees' code and is invalidated by a change
    of the kernel's own file only (the hammer's kernel_*.py share one digest for this reason):
    a string-side kernel calling a kernel of another module would keep stale code."""
    per_file = {}
    for path in _files():
        if path.parent.name != "fmu_src":
            continue
        tree = parse(path.read_text(encoding="utf-8"))
        per_file[path] = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and any(
            _decorator_name(d) in KERNEL_DECORATORS for d in n.decorator_list)]
    owner = {f.name: path for path, fs in per_file.items() for f in fs}
    bad = []
    for path, kernels in per_file.items():
        for f in kernels:
            for node in ast.walk(f):
                if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
                    other = owner.get(node.func.id)
                    if other is not None and other != path:
                        bad.append(f"{path.name}::{f.name} calls {other.name}::{node.func.id}")
    assert per_file and not bad, bad
