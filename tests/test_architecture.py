"""Architecture checks anyone can run: module size, import cycles, private names, import side effects.

The module graph is read from the sources with :mod:`ast` (nothing is imported),
counting imports inside functions too: an import deferred into a function is
still a dependency, and a cycle through it is still a cycle.
"""
from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from functools import lru_cache
from pathlib import Path

import pytest

from source_trees import nodes, parse

ROOT = Path(__file__).resolve().parents[1]
#: source directory -> the package it is imported as (pyproject.toml's package-dir)
PACKAGES = {ROOT / "coupling": "hammerbit", ROOT / "fmu_src": "hammerbit.model"}
#: a module longer than this holds more than one concept (tests and generated files aside)
MAX_LINES = 600
#: generated modules (written by a script, not read by people)
GENERATED = {"hammerbit.model.tableaux"}
#: modules still over the limit, each at most its length today (it may only shrink)
OVER_THE_LIMIT: dict = {}
#: a Python function longer than this (``def`` line to its last line) does more than one job
MAX_FUNCTION_LINES = 150
#: the sources that rule covers: the library and the benchmarks
FUNCTION_SOURCES = (ROOT / "coupling", ROOT / "fmu_src", ROOT / "benchmarks")
#: the solver driver ``advance`` and each of its pieces (issue 30: "each piece at most 80")
MAX_PIECE_LINES = 80


def _modules() -> dict:
    """{dotted module name: path} of every module of the library (coupling/ and fmu_src/)."""
    out = {}
    for src, pkg in PACKAGES.items():
        for path in sorted(src.rglob("*.py")):
            rel = path.relative_to(src).with_suffix("")
            parts = [p for p in rel.parts]
            if parts and parts[0] == "model" and pkg == "hammerbit":
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([pkg] + parts)] = path
    return out


MODULES = _modules()


def _is_package(name: str) -> bool:
    return MODULES[name].name == "__init__.py"


def _resolve(module: str, node: ast.ImportFrom) -> str:
    """The absolute module a ``from ... import`` names."""
    if node.level == 0:
        return node.module or ""
    base = module if _is_package(module) else module.rsplit(".", 1)[0]
    for _ in range(node.level - 1):
        base = base.rsplit(".", 1)[0]
    return f"{base}.{node.module}" if node.module else base


@lru_cache(maxsize=None)
def _imports(module: str) -> tuple:
    """(imported library module, the names taken from it, line) of every import in ``module``,
    at any depth (found once per process: several checks read them)."""
    return tuple(_find_imports(module))


def _find_imports(module: str):
    for node in nodes(MODULES[module].read_text(encoding="utf-8")):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name in MODULES:
                    yield a.name, (), node.lineno
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, node)
            for a in node.names:
                sub = f"{target}.{a.name}"
                if sub in MODULES:                     # from package import submodule
                    yield sub, (), node.lineno
                elif target in MODULES:
                    yield target, (a.name,), node.lineno


def _graph() -> dict:
    graph = {m: set() for m in MODULES}
    for m in MODULES:
        for target, _names, _line in _imports(m):
            if target != m:
                graph[m].add(target)
    return graph


def _cycles(graph: dict) -> list:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(graph)))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_checks_see_the_library():
    """The module list and the graph are not empty (a wrong path would pass every check)."""
    assert "hammerbit.cosim.master" in MODULES and "hammerbit.model.kernel_driver" in MODULES
    graph = _graph()
    assert "hammerbit.model.kernel_layouts" in graph["hammerbit.model.kernel_forces"]
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_the_checks_walk_every_node_of_a_file():
    """The shared walk (:func:`source_trees.nodes`) is :func:`ast.walk` of a fresh parse, node for
    node, on the longest modules (a walk cut short would pass every check below)."""
    longest = sorted(MODULES.values(), key=lambda p: len(p.read_bytes()))[-3:]
    for path in longest:
        source = path.read_text(encoding="utf-8")
        fresh = [ast.dump(n) for n in ast.walk(ast.parse(source))]
        assert [ast.dump(n) for n in nodes(source)] == fresh, path


def test_no_module_is_longer_than_the_limit():
    long = {m: n for m, p in MODULES.items() if m not in GENERATED
            and (n := len(p.read_text(encoding="utf-8").splitlines())) > OVER_THE_LIMIT.get(m, MAX_LINES)}
    assert not long, f"modules over {MAX_LINES} lines: {long}"


def test_no_import_cycle_counting_imports_inside_functions():
    assert _cycles(_graph()) == []


def test_no_private_name_is_imported_from_another_module():
    found = [f"{m}:{line}: from {target} import {name}" for m in MODULES
             for target, names, line in _imports(m) for name in names
             if name.startswith("_") and not name.startswith("__")]
    assert not found, "\n".join(found)


def test_every_module_says_what_it_is_on_its_first_line():
    missing = []
    for m, path in MODULES.items():
        doc = ast.get_docstring(parse(path.read_text(encoding="utf-8")))
        if not doc or len(doc.splitlines()[0].split()) < 3:
            missing.append(m)
    assert not missing, f"modules without a first docstring line saying what they are: {missing}"


def _function_lengths(source: str) -> list:
    """``(name, def line, lines from the def line to the last, decorated inline='always')`` of every
    function in ``source``, nested ones included (and counted in the function around them too)."""
    out = []
    for node in nodes(source):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            inlined = any(isinstance(d, ast.Call) and any(k.arg == "inline" and getattr(k.value, "value", None)
                                                          == "always" for k in d.keywords)
                          for d in node.decorator_list)
            out.append((node.name, node.lineno, node.end_lineno - node.lineno + 1, inlined))
    return out


def test_the_function_length_check_counts_lines():
    """From the ``def`` line to the last line, decorators aside, nested functions counted alone too;
    the inlined pieces are told apart."""
    src = ("@njit(inline='always')\ndef f(x):\n" + "    x += 1\n" * 10 + "    def g():\n        pass\n"
           "    return x\n\n\nclass C:\n    def h(self):\n        pass\n")
    assert sorted(_function_lengths(src)) == [("f", 2, 14, True), ("g", 13, 2, False), ("h", 19, 2, False)]
    files = [p for src_dir in FUNCTION_SOURCES for p in src_dir.rglob("*.py")]
    assert len(files) > 100 and any(p.name == "scipy_reference.py" for p in files)


def test_no_python_function_is_longer_than_150_lines():
    """Every function of coupling/, fmu_src/ and benchmarks/: at most MAX_FUNCTION_LINES lines."""
    long = [f"{path.relative_to(ROOT)}:{line} {name} ({n} lines)"
            for src_dir in FUNCTION_SOURCES for path in sorted(src_dir.rglob("*.py"))
            for name, line, n, _ in _function_lengths(path.read_text(encoding="utf-8")) if n > MAX_FUNCTION_LINES]
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines (split them into named pieces): {long}"


def test_the_solver_driver_and_its_pieces_are_short():
    """``advance`` and every function of the driver's module, and every piece the kernels inline
    (``njit(inline='always')``): at most MAX_PIECE_LINES lines each."""
    driver = MODULES["hammerbit.model.kernel_driver"]
    seen, long = set(), []
    for path in sorted(driver.parent.glob("kernel_*.py")):
        for name, line, n, inlined in _function_lengths(path.read_text(encoding="utf-8")):
            if path == driver or inlined:
                seen.add(name)
                if n > MAX_PIECE_LINES:
                    long.append(f"{path.name}:{line} {name} ({n} lines)")
    assert {"advance", "rk_advance", "stick_advance", "transition", "adaptive_step"} <= seen, sorted(seen)
    assert not long, f"driver pieces over {MAX_PIECE_LINES} lines: {long}"


_IMPORT_ALL = r"""
import importlib, json, os, sys
names = json.loads(sys.argv[1])
for name in names:
    importlib.import_module(name)
print(json.dumps({k: v for k, v in os.environ.items() if k.startswith("NUMBA_")}))
"""


def test_importing_the_library_creates_no_directory_and_sets_no_environment(tmp_path):
    """Import every module of the library in a fresh process with an empty HOME: no directory
    appears (the numba cache directory is numba's to create when it saves) and no ``NUMBA_*``
    variable is set."""
    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "HAMMERBIT_", "XDG_"))}
    env.update(HOME=str(home), PYTHONDONTWRITEBYTECODE="1", MPLCONFIGDIR=str(tmp_path / "mpl"))
    names = sorted(m for m in MODULES if not m.endswith("__main__") and "numba_compile_plan" not in m)
    r = subprocess.run([sys.executable, "-c", _IMPORT_ALL, json.dumps(names)], capture_output=True,
                       text=True, env=env, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert json.loads(r.stdout.strip().splitlines()[-1]) == {}
    assert sorted(p.name for p in home.rglob("*")) == []


#: a compiled kernel takes at most this many parameters; more are grouped into tuples
#: (the groups are listed in ``kernel_layouts``)
MAX_KERNEL_PARAMS = 10
#: kernels allowed more (at most their count today), each with the reason
MANY_PARAMS: dict = {
    # the native Drillstring FMU's C entry point: its parameters are the C ABI that
    # native/model_string.c calls (pointers and sizes); its body groups them into the
    # exchange's records before it calls a kernel
    "hammerbit.fmu.native_string_kernels.hs_exchange": 24,
}
_COMPILERS = {"njit", "jit", "cfunc"}


def _compiler_name(node) -> str:
    """``njit`` for ``njit``, ``numba.njit``, ``njit(...)`` and ``numba.njit(...)``; else ''."""
    if isinstance(node, ast.Call):
        node = node.func
    if isinstance(node, ast.Attribute):
        return node.attr if node.attr in _COMPILERS else ""
    if isinstance(node, ast.Name):
        return node.id if node.id in _COMPILERS else ""
    return ""


def _kernel_params(source: str) -> dict:
    """{function name: number of parameters} of the functions compiled by numba in ``source``:
    decorated with ``njit``/``jit``/``cfunc`` (bare or called), or passed to one as
    ``njit(...)(f)`` or ``njit(...)(bind(f, ...))``."""
    defs = {n.name: n for n in nodes(source) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}
    compiled = {name for name, d in defs.items() if any(_compiler_name(dec) for dec in d.decorator_list)}
    for node in nodes(source):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Call) and _compiler_name(node.func) \
                and node.args:
            target = node.args[0]
            if isinstance(target, ast.Call) and target.args:     # njit(...)(bind(f, ...)): f's copy
                target = target.args[0]
            if isinstance(target, ast.Name) and target.id in defs:
                compiled.add(target.id)

    def count(d):
        a = d.args
        return len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + (a.vararg is not None) + (a.kwarg is not None)
    return {name: count(defs[name]) for name in compiled}


def test_the_kernel_parameter_check_sees_the_kernels():
    """The checker finds decorated and wrapped kernels and counts their parameters."""
    src = ("from numba import njit, cfunc\nimport numba\n"
           "@njit(cache=True)\ndef a(x, y):\n    pass\n"
           "@numba.njit\ndef b(x):\n    pass\n"
           "def c(p, q, r):\n    pass\n"
           "d = njit(cache=True)(bind(c, 'd', r=1))\n"
           "def f():\n    @cfunc('int64(int64)')\n    def e(k):\n        return k\n"
           "def plain(a, b, c, d, e, f, g, h, i, j, k):\n    pass\n")
    assert _kernel_params(src) == {"a": 2, "b": 1, "c": 3, "e": 1}
    driver = _kernel_params(MODULES["hammerbit.model.kernel_driver"].read_text(encoding="utf-8"))
    assert "advance" in driver and "constants" in driver


def test_no_kernel_takes_more_than_ten_parameters():
    """Every numba kernel of the library (fmu_src/ and coupling/) takes at most
    MAX_KERNEL_PARAMS parameters: longer argument lists are grouped into the tuples of
    ``kernel_layouts`` (method, sub, field, step, scratch, rec)."""
    over = {}
    for m, path in MODULES.items():
        for name, n in _kernel_params(path.read_text(encoding="utf-8")).items():
            if n > MAX_KERNEL_PARAMS and MANY_PARAMS.get(f"{m}.{name}", MAX_KERNEL_PARAMS) < n:
                over[f"{m}.{name}"] = n
    assert not over, f"kernels with more than {MAX_KERNEL_PARAMS} parameters: {over}"
