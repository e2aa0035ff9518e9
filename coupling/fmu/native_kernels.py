"""The model's numba kernels as object files for the native FMU: C entry points, LLVM IR, objects.

The native flavour of ``HammerBitRock.fmu`` runs the library's own kernels
(``hammerbit.model.kernel_*``), compiled ahead of time for each target
platform, so the FMU needs neither Python nor numba.  The steps:

1. numba ``cfunc`` entry points with a C ABI (pointers to the state, option
   and parameter arrays; :data:`ENTRY_POINTS`) call the kernels: the solver
   driver ``advance_hammer`` and, for Model Exchange, the vector field, the
   event indicators and the reset map;
2. their LLVM IR (``inspect_llvm()``, which holds every kernel they call) is
   parsed with llvmlite and linked into one module; each entry point gets a
   plain C name (``hb_advance`` ...), every other definition becomes internal;
3. the module is optimised and emitted for a target triple and the portable
   CPU ``x86-64`` (no host-specific instructions) as an object file.

The objects reference libm and a few helpers of numba's runtime (``NRT_*``
allocation of the driver's scratch arrays, and the ``Py*``/``numba_*``
functions of the error path of a cfunc); ``native/nrt_shim.c`` provides them.
:func:`undefined_symbols` lists what an object needs, so the build can
refuse an object that needs anything else.

Compiling needs numba to compile the kernels afresh (a cached kernel carries
no IR) for the portable CPU: :func:`build_objects` runs :func:`main` in a
subprocess with an empty kernel cache and ``NUMBA_CPU_NAME=generic``.
"""
from __future__ import annotations

import json
import re
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from hammerbit.fmu.native_forces import forces_entry_point

__all__ = ["TARGETS", "ENTRY_POINTS", "KernelBuildError", "Target", "LAYOUT_NAMES", "layout",
           "compile_entry_points", "linked_ir", "emit_object", "undefined_symbols",
           "ALLOWED_UNDEFINED", "build_objects"]


class KernelBuildError(RuntimeError):
    """The kernels could not be compiled into object files (the message says which step)."""


@dataclass(frozen=True)
class Target:
    """A platform the native FMU is built for."""

    platform: str      #: FMI binaries directory name (linux64, win64)
    triple: str        #: LLVM target triple
    suffix: str        #: shared-library suffix (.so, .dll)
    #: the CPU the object is emitted for: the architecture's baseline, which every CPU of it runs
    #: (x86-64: SSE2)
    cpu: str = "x86-64"


#: the platforms of the native flavour; win64 is linked by mingw-w64, aarch64-linux (FMI 3.0's
#: name; the FMI 3.0 FMU only) by aarch64-linux-gnu-gcc, for the AArch64 baseline (ARMv8-A)
TARGETS = {
    "linux64": Target("linux64", "x86_64-unknown-linux-gnu", ".so"),
    "win64": Target("win64", "x86_64-w64-windows-gnu", ".dll"),
    "aarch64-linux": Target("aarch64-linux", "aarch64-unknown-linux-gnu", ".so", cpu="generic"),
}


#: C names of the entry points and their C prototypes (kernel_api.h in native/ declares the same)
ENTRY_POINTS = {
    "hb_advance": "int64_t hb_advance(double *y, int64_t *ist, double *fst, double tau_end, "
                  "double *p, double *opts)",
    "hb_advance_to_event": "int64_t hb_advance_to_event(double *y, int64_t *ist, double *fst, "
                           "double tau_end, double *p, double *opts, double *log)",
    "hb_init_modes": "int64_t hb_init_modes(double *y, int64_t *ist, double *p)",
    "hb_forces": "int64_t hb_forces(double *y, int64_t *ist, double *p, double *out)",
    "hb_rhs": "int64_t hb_rhs(double tau, double *y, double *p, int64_t mode_s, int64_t mode_c, "
              "double *out)",
    "hb_watched": "int64_t hb_watched(int64_t *ist, double *p, int64_t *kinds)",
    "hb_watch_value": "double hb_watch_value(int64_t kind, double *y, double *p, int64_t mode_c)",
    "hb_apply_event": "int64_t hb_apply_event(int64_t kind, double *y, int64_t *ist, double *fst, "
                      "double *p)",
    "hb_oscillator_l1": "int64_t hb_oscillator_l1(double rho, double xi, double *l1)",
    "hb_regime": "int64_t hb_regime(double *y, int64_t *ist, double *fst, double *p, double *l1, "
                 "double *cert)",
}

#: symbols an object may leave to the C side: libm, and what native/nrt_shim.c defines
ALLOWED_UNDEFINED = frozenset({
    # libm (what LLVM lowers the math intrinsics to, per platform)
    "exp", "pow", "sin", "cos", "sincos", "log", "floor", "ceil", "sqrt", "fabs", "fmod", "tan", "atan",
    "atan2", "log1p", "expm1", "cosh", "sinh", "tanh", "memset", "memcpy", "memmove",
    # numba's runtime helpers the shim provides
    "NRT_MemInfo_alloc_aligned", "NRT_MemInfo_call_dtor", "NRT_Free", "numba_gil_ensure",
    "numba_gil_release", "numba_unpickle", "numba_do_raise", "numba_runtime_build_excinfo_struct",
    "PyUnicode_FromString", "PyErr_WriteUnraisable", "Py_DecRef", "PyErr_Clear",
    "PyBytes_FromStringAndSize", "PyErr_SetString", "PyErr_SetNone", "PyErr_SetObject",
    "PyErr_Occurred", "PyErr_Fetch", "PyErr_Restore", "PyExc_RuntimeError",
    # mingw-w64 stack probe of large frames
    "___chkstk_ms", "__chkstk",
})

#: kernel layout constants the C side reads from the generated header (``layout()``)
LAYOUT_NAMES = (
    "N_ISTATE", "N_FSTATE", "N_OPTS", "I_STICK", "I_CONTACT", "I_BOUNCE", "I_WIN", "I_COUNT0",
    "I_POIN_NEXT", "I_SAMP_NEXT", "I_NLOG", "I_SWIN", "L_T", "L_KIND", "N_LOG_COLS",
    "F_T", "F_H", "STICK", "SLIP", "FREE", "CONTACT", "CLAMPED", "EV_SLIP_START", "EV_STICK",
    "EV_SLIP_ON", "EV_IMPACT", "EV_SEPARATION", "EV_CLAMP", "EV_UNCLAMP", "EV_BOUNCE",
    "EV_BOUNCE_END", "N_EVENT_KINDS", "O_RTOL", "O_ATOL", "O_HMAX", "O_HFIXED", "O_EVCAP",
    "O_BISECT", "O_MAXSTEPS", "O_POIN_T0", "O_POIN_DT", "O_GRAZE", "O_STEPCAP", "ST_DONE",
    "ST_LOG_FULL", "ST_EVENT_STORM", "ST_STEP_TOO_SMALL", "ST_NONFINITE", "ST_MAX_STEPS",
    "ST_STEP_STORM", "ST_BAD_INPUT", "V_BIT", "X_BIT",
)
_PARAM_NAMES = ("P_RHO", "P_XI", "P_ETA", "P_A", "P_B", "P_R", "P_MU", "P_GAMMA", "P_KC", "P_N",
                "P_LAM", "P_PHI", "P_FEXT", "P_CONTACT", "N_P")
#: the size of the watched-kinds buffer of hb_watched (``kernels.watched`` fills at most 3)
WATCH_SLOTS = 4


def layout() -> dict:
    """``{name: int}``: the kernels' array layout (offsets, modes, event kinds, status codes)."""
    from hammerbit.model import kernel_layouts as KL
    out = {name: int(getattr(KL, name)) for name in LAYOUT_NAMES + _PARAM_NAMES}
    out["WATCH_SLOTS"] = WATCH_SLOTS
    from hammerbit.model.regime import N_CERT
    out["N_CERT"] = N_CERT
    return out


# ---------------------------------------------------------------------------
# 1. entry points (compiled in this process)
# ---------------------------------------------------------------------------
def compile_entry_points() -> dict:
    """``{C name: numba cfunc}`` of :data:`ENTRY_POINTS` (compiles them in this process)."""
    import numpy as np
    from numba import carray, cfunc, types
    from numba.core.types import CPointer, float64, int64

    from hammerbit.model import kernel_driver as KD
    from hammerbit.model import kernel_events as KE
    from hammerbit.model import kernel_forces as KF
    from hammerbit.model import kernel_layouts as KL
    from hammerbit.model import kernel_reset as KR

    f64p, i64p = CPointer(float64), CPointer(int64)
    NI, NF, NO, N_P = KL.N_ISTATE, KL.N_FSTATE, KL.N_OPTS, KL.N_P
    NS, NL = KL.N_SAMPLE_COLS, KL.N_LOG_COLS
    NY = 4                                     # x1..x4: the FMU has no subsystem, no energy block
    advance_hammer, rhs, watched, watch_value = KD.advance_hammer, KF.rhs, KE.watched, KE.watch_value
    apply_event, overlap, impact_mode = KR.apply_event, KF.overlap, KF.contact_mode_at_impact
    I_STICK, I_CONTACT, I_WIN, P_CONTACT = KL.I_STICK, KL.I_CONTACT, KL.I_WIN, KL.P_CONTACT
    STICK, SLIP, FREE, CONTACT, V_BIT = KL.STICK, KL.SLIP, KL.FREE, KL.CONTACT, KL.V_BIT
    no_sub = KD.NO_SUB                         # the FMU has no linear subsystem

    @cfunc(int64(f64p, i64p, f64p, float64, f64p, f64p))
    def hb_advance(yp, ip, fp, tau_end, pp, op):
        # the record buffers the FMU does not use are empty (what Stepper passes when none is asked)
        return advance_hammer(carray(yp, (NY,)), carray(ip, (NI,)), carray(fp, (NF,)), tau_end,
                              carray(pp, (N_P,)), carray(op, (NO,)), (np.empty((0, 5)), np.empty(0),
                                                                      np.empty((0, NS)), np.empty((0, NL))))

    @cfunc(int64(f64p, i64p, f64p, float64, f64p, f64p, f64p))
    def hb_advance_to_event(yp, ip, fp, tau_end, pp, op, lp):
        # an event log of one row (the caller zeroes ist[I_NLOG]): the driver returns ST_LOG_FULL
        # at the first event, its reset applied, as Stepper.advance does with such a log
        return advance_hammer(carray(yp, (NY,)), carray(ip, (NI,)), carray(fp, (NF,)), tau_end,
                              carray(pp, (N_P,)), carray(op, (NO,)), (np.empty((0, 5)), np.empty(0),
                                                                      np.empty((0, NS)), carray(lp, (1, NL))))

    @cfunc(int64(f64p, i64p, f64p))
    def hb_init_modes(yp, ip, pp):
        # the modes of a state at rest, as Stepper does at construction
        y, ist, p = carray(yp, (NY,)), carray(ip, (NI,)), carray(pp, (N_P,))
        ist[I_STICK] = SLIP if y[V_BIT] > 0.0 else STICK
        if p[P_CONTACT] > 0.0 and overlap(y, p) > 0.0:
            ist[I_CONTACT] = impact_mode(y, p)
        else:
            ist[I_CONTACT] = FREE
        ist[I_WIN] = -1
        return 0

    hb_forces = forces_entry_point()

    @cfunc(int64(float64, f64p, f64p, int64, int64, f64p))
    def hb_rhs(tau, yp, pp, ms, mc, op):
        rhs(tau, carray(yp, (NY,)), (carray(pp, (N_P,)), ms, mc, no_sub), carray(op, (NY,)))
        return 0

    @cfunc(int64(i64p, f64p, i64p))
    def hb_watched(ip, pp, kp):
        return watched(carray(ip, (NI,)), carray(pp, (N_P,)), carray(kp, (WATCH_SLOTS,)))

    @cfunc(float64(int64, f64p, f64p, int64))
    def hb_watch_value(kind, yp, pp, mc):
        return watch_value(kind, carray(yp, (NY,)), carray(pp, (N_P,)), mc)

    @cfunc(int64(int64, f64p, i64p, f64p, f64p))
    def hb_apply_event(kind, yp, ip, fp, pp):
        return apply_event(kind, carray(yp, (NY,)), carray(ip, (NI,)), carray(fp, (NF,)),
                           carray(pp, (N_P,)))

    hb_oscillator_l1, hb_regime = _regime_entry_points()
    funcs = {"hb_advance": hb_advance, "hb_advance_to_event": hb_advance_to_event,
             "hb_init_modes": hb_init_modes, "hb_forces": hb_forces,
             "hb_rhs": hb_rhs, "hb_watched": hb_watched, "hb_watch_value": hb_watch_value,
             "hb_apply_event": hb_apply_event, "hb_oscillator_l1": hb_oscillator_l1, "hb_regime": hb_regime}
    assert set(funcs) == set(ENTRY_POINTS)
    return funcs


def _regime_entry_points():
    """``hb_oscillator_l1`` (the regime certificate's L1 norms of rho, xi, into l1[2]) and
    ``hb_regime`` (``fmu_regime.causal_regime``, with l1[2] and a scratch cert[N_CERT])."""
    from numba import carray, cfunc
    from numba.core.types import CPointer, float64, int64

    from hammerbit.model import kernel_layouts as KL
    from hammerbit.model.fmu_regime import N_CERT, causal_regime
    from hammerbit.model.regime import oscillator_l1
    f64p, i64p = CPointer(float64), CPointer(int64)
    NI, NF, N_P = KL.N_ISTATE, KL.N_FSTATE, KL.N_P

    @cfunc(int64(float64, float64, f64p))
    def hb_oscillator_l1(rho, xi, lp):
        l1 = carray(lp, (2,))
        l1[0], l1[1] = oscillator_l1(rho, xi)
        return 0

    @cfunc(int64(f64p, i64p, f64p, f64p, f64p, f64p))
    def hb_regime(yp, ip, fp, pp, lp, cp):
        l1 = carray(lp, (2,))
        return causal_regime(carray(yp, (4,)), carray(ip, (NI,)), carray(fp, (NF,)), carray(pp, (N_P,)),
                             l1[0], l1[1], carray(cp, (N_CERT,)))
    return hb_oscillator_l1, hb_regime


# ---------------------------------------------------------------------------
# 2. LLVM IR of the entry points, linked into one module
# ---------------------------------------------------------------------------
def _llvm():
    import llvmlite.binding as llvm
    llvm.initialize_all_targets()
    llvm.initialize_all_asmprinters()
    return llvm


def linked_ir(funcs: dict, entry_points=None) -> str:
    """One LLVM module with every entry point under its C name and nothing else exported
    (``entry_points``: the C names it must hold, default :data:`ENTRY_POINTS`)."""
    llvm = _llvm()
    module = None
    names = {}
    for cname, fn in funcs.items():
        mod = llvm.parse_assembly(fn.inspect_llvm())
        names[fn.native_name] = cname
        if module is None:
            module = mod
        else:
            module.link_in(mod)
    for f in module.functions:
        if f.is_declaration:
            continue
        if f.name in names:
            f.name = names[f.name]
            f.linkage = llvm.Linkage.external
            # the library's exports are the FMI functions only (ELF; a DLL exports what it marks)
            f.visibility = llvm.Visibility.hidden
        else:
            f.linkage = llvm.Linkage.internal
    for g in module.global_variables:
        if not g.is_declaration:
            g.linkage = llvm.Linkage.internal
    missing = set(ENTRY_POINTS if entry_points is None else entry_points) - {f.name for f in module.functions if not f.is_declaration}
    if missing:
        raise KernelBuildError(f"the linked kernel module lacks the entry points {sorted(missing)}")
    module.verify()
    return str(module)


# ---------------------------------------------------------------------------
# 3. object files
# ---------------------------------------------------------------------------
#: numba's optimiser (run for x86-64) turns NRT_decref's atomic decrement and test for zero into
#: an x86 intrinsic (condition code 4: equal, the result is zero); other targets get the generic
#: IR it stands for
_X86_ATOMIC_SUB_CC = re.compile(r"(%[\w.]+) = (?:tail )?call i8 @llvm\.x86\.atomic\.sub\.cc\.i64\("
                                r"ptr (?:nonnull )?(%[\w.]+), i64 (-?\d+), i32 4\)")


def generic_atomics(ir: str) -> str:
    """``ir`` without x86 atomic intrinsics (for a target that is not x86-64); raises
    :class:`KernelBuildError` on one it does not know."""
    count = iter(range(1 << 30))

    def replace(m):
        res, ptr, v = m.groups()
        k = next(count)
        return (f"%hb.atomic{k}.old = atomicrmw sub ptr {ptr}, i64 {v} seq_cst\n"
                f"  %hb.atomic{k}.zero = icmp eq i64 %hb.atomic{k}.old, {v}\n"
                f"  {res} = zext i1 %hb.atomic{k}.zero to i8")
    out = _X86_ATOMIC_SUB_CC.sub(replace, ir)
    out = "\n".join(line for line in out.splitlines() if not line.startswith("declare i8 @llvm.x86.atomic.sub.cc"))
    if "@llvm.x86." in out:
        raise KernelBuildError("the kernels' IR uses x86 intrinsics the non-x86 build cannot translate: "
                               + ", ".join(sorted(set(re.findall(r"@llvm\.x86\.[\w.]+", out)))))
    return out


def emit_object(ir: str, target: Target) -> bytes:
    """Object file of ``ir`` for ``target`` and the portable CPU (optimised; unused code removed)."""
    llvm = _llvm()
    if not target.triple.startswith("x86_64"):
        ir = generic_atomics(ir)
    mod = llvm.parse_assembly(ir)
    # numba ran with NUMBA_CPU_NAME=generic: its IR carries no CPU attributes; the target machine
    # emits for the baseline CPU
    tm = llvm.Target.from_triple(target.triple).create_target_machine(
        cpu=target.cpu, features="", opt=3, reloc="pic", codemodel="default")
    mod.triple = target.triple
    mod.data_layout = str(tm.target_data)
    pto = llvm.create_pipeline_tuning_options(speed_level=2)
    pb = llvm.create_pass_builder(tm, pto)
    pb.getModulePassManager().run(mod, pb)
    mod.verify()
    return tm.emit_object(mod)


def undefined_symbols(obj: Path, *, nm: str = "nm") -> set:
    """Names an object file leaves undefined (``nm -u``; a leading underscore of COFF kept)."""
    r = subprocess.run([nm, "-u", str(obj)], capture_output=True, text=True)
    if r.returncode != 0:
        raise KernelBuildError(f"{nm} -u {obj} failed: {r.stderr.strip()}")
    return {line.split()[-1] for line in r.stdout.splitlines() if line.strip()}


def _kernel_set(name: str):
    """``(compile function, entry points)`` of a kernel set: ``hammer`` (HammerBitRock),
    ``string`` (Drillstring) or ``system`` (DrillingSystem)."""
    if name == "string":
        from hammerbit.fmu.native_string_kernels import STRING_ENTRY_POINTS, compile_string_entry_points
        return compile_string_entry_points, STRING_ENTRY_POINTS
    if name == "system":
        from hammerbit.fmu.native_system_kernels import SYSTEM_ENTRY_POINTS, compile_system_entry_points
        return compile_system_entry_points, SYSTEM_ENTRY_POINTS
    if name == "hammer":
        return compile_entry_points, ENTRY_POINTS
    raise KernelBuildError(f"unknown kernel set {name!r}; known: hammer, string, system")


#: the kernel sets of :func:`build_objects`
KERNEL_SETS = ("hammer", "string", "system")


def main(argv=None) -> int:
    """``python -m hammerbit.fmu.native_kernels [--kernels SET] OUT_DIR PLATFORM...``: write
    ``kernels_<platform>.o`` of the kernel set (``hammer``, default, or ``string``).

    Run by :func:`build_objects` in a process with the portable CPU target and
    an empty kernel cache.  Prints a JSON summary (layout, object sizes).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    kernels = "hammer"
    if argv and argv[0] == "--kernels":
        kernels, argv = argv[1], argv[2:]
    compile_fn, entry_points = _kernel_set(kernels)
    out_dir = Path(argv[0])
    funcs = compile_fn()
    ir = linked_ir(funcs, entry_points)
    sizes = {}
    for plat in argv[1:]:
        obj = emit_object(ir, TARGETS[plat])
        path = out_dir / f"kernels_{plat}.o"
        path.write_bytes(obj)
        sizes[plat] = len(obj)
    print(json.dumps({"layout": layout(), "sizes": sizes}))
    return 0


def sources_key(platforms, kernels: str = "hammer") -> str:
    """Hash of what the objects are made of: the runtime's sources, this module, numba, llvmlite."""
    import hashlib
    from importlib.metadata import version

    from hammerbit import model
    h = hashlib.sha256()
    for f in sorted(Path(model.__file__).resolve().parent.glob("*.py"), key=lambda p: p.name):
        if f.name != "build_info.py":          # rewritten by the Python flavour's build
            h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    h.update(Path(__file__).read_bytes())
    for name in ("native_string_kernels.py", "native_system_kernels.py", "native_forces.py"):
        h.update((Path(__file__).parent / name).read_bytes())
    h.update(f"kernels {kernels} numba {version('numba')} llvmlite {version('llvmlite')} {sorted(platforms)}".encode())
    return h.hexdigest()[:16]


#: the lock file of a kept entry, held while one build compiles it
KEPT_LOCK = ".compile-lock"


def _kept_dir(key: str):
    """``<user cache>/native-kernels/<key>`` (None if the user cache cannot be written)."""
    from hammerbit.model.numba_cache_place import user_cache_root
    d = Path(user_cache_root()) / "native-kernels" / key
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return d


def build_objects(out_dir, platforms=("linux64", "win64"), *, python: str = sys.executable,
                  timeout: float = 1800, kernels: str = "hammer") -> dict:
    """Compile the kernels into ``out_dir/kernels_<platform>.o``; return ``{"layout", "sizes"}``.

    Runs :func:`main` in a subprocess: numba there compiles for the portable
    CPU (``NUMBA_CPU_NAME=generic``) into an empty cache directory, so the IR
    of every kernel is at hand.  The objects are kept in the user cache
    (``native-kernels/<hash of the sources and versions>``), so a rebuild of
    the same sources takes seconds.  The kept entry holds every platform of
    :data:`TARGETS` (the kernels' numba compile, the costly part, is the same
    for all; each object is one more code generation), so an FMI 3.0 build after
    an FMI 2.0 one, or one for other platforms, compiles nothing; and builds of
    the same sources at the same time (FMUs built in parallel) compile them once:
    the others wait for the kept objects.  Raises :class:`KernelBuildError`.
    """
    from hammerbit.model.numba_compile_lock import file_lock
    unknown = sorted(set(platforms) - set(TARGETS))
    if unknown:
        raise KernelBuildError(f"platforms {unknown} are out of range: allowed {sorted(TARGETS)}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    kept = _kept_dir(sources_key(sorted(TARGETS), kernels))
    if kept is None:
        return _compile_objects(out_dir, platforms, python=python, timeout=timeout, kernels=kernels)
    with file_lock(str(kept / KEPT_LOCK)):
        summary = kept / "summary.json"
        if not summary.is_file():
            everything = _compile_objects(kept, list(TARGETS), python=python, timeout=timeout, kernels=kernels)
            tmp = kept / "summary.json.tmp"
            tmp.write_text(json.dumps(everything))
            os.replace(tmp, summary)     # last: a complete entry or none
        for plat in platforms:
            shutil.copyfile(kept / f"kernels_{plat}.o", out_dir / f"kernels_{plat}.o")
        result = json.loads(summary.read_text())
    return {"layout": result["layout"], "sizes": {p: result["sizes"][p] for p in platforms}}


def _compile_objects(out_dir: Path, platforms, *, python: str, timeout: float, kernels: str) -> dict:
    from hammerbit.model.numba_target import PORTABLE_ENV
    with tempfile.TemporaryDirectory(prefix="hammerbit_kernels_") as cache:
        env = dict(os.environ, HAMMERBIT_CACHE_DIR=cache, NUMBA_CACHE_DIR=cache,
                   PYTHONDONTWRITEBYTECODE="1", **PORTABLE_ENV)
        try:
            r = subprocess.run([python, "-m", "hammerbit.fmu.native_kernels", "--kernels", kernels,
                                str(out_dir), *platforms],
                               capture_output=True, text=True, env=env, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise KernelBuildError(f"compiling the kernels took more than {timeout:g} s") from None
    if r.returncode != 0:
        raise KernelBuildError(f"compiling the kernels into object files failed (exit {r.returncode}):\n"
                               f"{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    sys.exit(main())
