"""The C timing host of the FMU benchmarks (``fmu_step_host.c``): built here, run on extracted FMUs.

FMI toolchains (libcosim, ecos, Simulink, Dymola) are C/C++ masters: a call into an FMU costs
them nanoseconds, so the warm cost of ``fmi2SetReal`` + ``fmi2DoStep`` + ``fmi2GetReal`` as they
pay it is measured from C.  The host loads several FMUs into one process and times blocks of
steps of each, alternating (ABBA), in CPU and wall-clock time; see the header of
``fmu_step_host.c``.

A pythonfmu FMU's library takes the Python C-API from the process: the host opens this
Python's shared ``libpython`` first (``preload=``) and runs with ``PYTHONHOME`` set to its prefix.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["HOST_SOURCE", "HostUnavailable", "HostedFMU", "hosted_fmu", "build_step_host",
           "shared_libpython", "run_step_host"]

#: the host's C source (built against fmpy's copy of the standard FMI 2.0 headers)
HOST_SOURCE = Path(__file__).resolve().with_name("fmu_step_host.c")


class HostUnavailable(RuntimeError):
    """The C host cannot be built or run here (the message says what is missing)."""


@dataclass(frozen=True)
class HostedFMU:
    """One FMU as the host drives it: its extracted directory, the Real input set before every
    step (``vr_in`` = ``value``), the Real output read after it (``vr_out``), and Reals set in
    Initialization Mode (``init``: ``{value reference: value}``)."""
    name: str
    directory: Path
    guid: str
    model_identifier: str
    vr_in: int
    value: float
    vr_out: int
    init: dict = field(default_factory=dict)

    def args(self) -> list:
        so = self.directory / "binaries" / "linux64" / f"{self.model_identifier}.so"
        return ["--", self.name, str(so), (self.directory / "resources").as_uri(), self.guid,
                str(self.vr_in), repr(float(self.value)), str(self.vr_out),
                *(f"{vr}={float(v)!r}" for vr, v in self.init.items())]


def hosted_fmu(directory, name: str, input_name: str, value: float, output_name: str,
               init=None) -> HostedFMU:
    """A :class:`HostedFMU` from an extracted FMU and variable names (``init``: ``{name: value}``)."""
    from fmpy import read_model_description
    directory = Path(directory)
    md = read_model_description(str(directory / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    missing = [n for n in (input_name, output_name, *(init or {})) if n not in vr]
    if missing:
        raise ValueError(f"{name}: no variables {missing} in {directory / 'modelDescription.xml'}")
    return HostedFMU(name, directory, md.guid, md.coSimulation.modelIdentifier, vr[input_name],
                     float(value), vr[output_name], {vr[k]: float(v) for k, v in (init or {}).items()})


def build_step_host(dest_dir) -> Path:
    """Compile the host into ``dest_dir``; raises :class:`HostUnavailable` without a C compiler."""
    import fmpy

    from hammerbit.fmu.native import FrontBuildError, find_compiler
    if not sys.platform.startswith("linux"):
        raise HostUnavailable(f"the C timing host is built for Linux only (this is {sys.platform})")
    try:
        cc = find_compiler()
    except FrontBuildError as e:
        raise HostUnavailable(f"no C compiler for the C timing host: {e}") from None
    exe = Path(dest_dir) / "fmu_step_host"
    r = subprocess.run([cc, "-O2", "-I", str(Path(fmpy.__file__).parent / "c-code"), "-o", str(exe),
                        str(HOST_SOURCE), "-ldl"], capture_output=True, text=True)
    if r.returncode != 0:
        raise HostUnavailable(f"compiling {HOST_SOURCE.name} with {cc} failed: {r.stderr[-2000:]}")
    return exe


def shared_libpython() -> Path | None:
    """This Python's shared ``libpython``, or None (a ``--disable-shared`` build has none)."""
    v = sysconfig.get_config_var
    names = [n for n in (v("INSTSONAME"), v("LDLIBRARY")) if n and ".so" in n]
    dirs = [v("LIBDIR") or "", os.path.join(v("LIBDIR") or "", v("MULTIARCH") or "")]
    return next((Path(d) / n for d in dirs for n in names if (Path(d) / n).is_file()), None)


def run_step_host(host, fmus, *, steps: int, pairs: int, h: float, python: bool = False,
                  timeout: float = 1800) -> dict:
    """Run the host on ``fmus`` (:class:`HostedFMU`); its JSON as a dict.

    ``python``: one of the FMUs is a pythonfmu FMU, so this Python's ``libpython`` is opened first
    and ``PYTHONHOME`` points at its prefix (raises :class:`HostUnavailable` if it has none)."""
    cmd = [str(host), str(int(steps)), str(int(pairs)), repr(float(h))]
    env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": os.environ.get("HOME", "/tmp")}
    if python:
        lib = shared_libpython()
        if lib is None:
            raise HostUnavailable(f"{sys.executable} has no shared libpython, which a pythonfmu FMU "
                                  f"needs in a C host")
        cmd.append(f"preload={lib}")
        env["PYTHONHOME"] = sys.base_prefix
    for f in fmus:
        cmd += f.args()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    if r.returncode != 0:
        raise RuntimeError(f"{Path(host).name} failed ({r.returncode}): {r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])
