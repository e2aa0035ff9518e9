"""Builds shared by a test session's workers: the first worker that asks builds, the others wait and reuse it.

pytest-xdist gives each worker its own session, so a session fixture would build the same FMU
once per worker; the workers' base temporary directories share a parent for the run, and a file
lock there makes one build serve them all.  A build that fails marks nothing, so the next worker
tries again (and fails the same way, in its own tests)."""
import os
from pathlib import Path

from hammerbit.model.numba_compile_lock import file_lock


def shared_dir(tmp_path_factory, name: str) -> Path:
    """The run's directory ``name`` for shared builds (the same for every worker of the run)."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent
    return base / "shared-builds" / name


def shared_build(tmp_path_factory, name: str, filename: str, build):
    """``build(directory / filename)`` once per run across the workers; returns what it returned
    (a path), from whichever worker built it."""
    d = shared_dir(tmp_path_factory, name)
    d.mkdir(parents=True, exist_ok=True)
    with file_lock(str(d.parent / f"{name}.lock")):
        done = d / ".built"
        if not done.exists():
            result = build(d / filename)
            done.write_text(str(result))
        return Path(done.read_text())
