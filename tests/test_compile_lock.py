"""One first compile of an entry point per cache at a time (``numba_compile_lock``): the lock
excludes another holder, only the compile is held, and parallel processes compile once."""
from __future__ import annotations

import contextlib
import fcntl
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from hammerbit.model import numba_cache
from hammerbit.model import numba_compile_lock
from hammerbit.model import stepping
from hammerbit.model.presets import preset


def _try_lock(path) -> bool:
    """True if a new open file of ``path`` can take the lock now (flock: per open file, so this
    process's own holder excludes it too)."""
    fd = os.open(path, os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    finally:
        os.close(fd)


def test_the_lock_excludes_another_holder_until_released():
    entry = f"test-entry-{os.getpid()}"
    with numba_compile_lock.compiling(entry):
        path = numba_compile_lock.lock_path(entry)
        assert os.path.dirname(path) == numba_cache.cache_root()
        assert not _try_lock(path)
    assert _try_lock(path)
    with pytest.raises(KeyboardInterrupt):       # an interrupted compile lets go too
        with numba_compile_lock.compiling(entry):
            raise KeyboardInterrupt
    assert _try_lock(path)
    os.remove(path)


def test_an_unwritable_cache_compiles_unlocked(monkeypatch, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setattr(numba_cache, "cache_root", lambda: str(blocker / "cache"))
    with numba_compile_lock.compiling("advance_hammer"):
        pass
    assert not (blocker.parent / "cache").exists()


def test_a_first_compile_holds_the_lock_for_a_call_that_keeps_the_state(monkeypatch):
    """On a cache miss the stepper calls the kernel once under the lock, to its own time (a compile,
    no step), and integrates after the lock is let go; the run ends as one without that path."""
    g = preset("paper-fig9").replace(a=0.083)
    ref = stepping.Stepper(g, compile_helper=False)
    ref.advance(40.0)
    held, calls = [], []

    @contextlib.contextmanager
    def recording(entry):
        held.append(entry)
        yield
        held.append(None)

    st = stepping.Stepper(g, compile_helper=False)
    start = st.time
    real_call = st._call
    monkeypatch.setattr(st, "_call", lambda t_end, rec: (calls.append((t_end, held[-1] if held else None)),
                                                         real_call(t_end, rec))[1])
    monkeypatch.setattr(numba_compile_lock, "compiling", recording)
    monkeypatch.setattr(stepping, "notice_checked", lambda entry: False)
    monkeypatch.setattr(stepping, "compile_notice", lambda entry: True)
    st.advance(40.0)
    assert held == [st.entry, None]
    assert calls == [(start, st.entry), (40.0, None)]
    assert np.array_equal(st.state_buffer, ref.state_buffer)


@pytest.mark.slow
def test_two_processes_on_an_empty_cache_compile_the_entry_point_once(tmp_path):
    """Started together on an empty cache, two processes run one scene; numba saves the entry
    point's compiled code once (the other process loads it), and both get the same bits."""
    code = ("from hammerbit.scene.simulate import simulate\nfrom hammerbit.model.presets import preset\n"
            "r = simulate(preset('paper-fig9').replace(a=0.083), 20)\nprint(repr(r.final.tolist()))\n")
    env = dict(os.environ, HAMMERBIT_CACHE_DIR=str(tmp_path / "cache"), NUMBA_DEBUG_CACHE="1")
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, env=env) for _ in range(2)]
    outs = [p.communicate(timeout=1800) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1][-2000:] for o in outs]
    saved = [len(re.findall(r"data saved to .*kernel_driver\.advance_hammer-", o[0] + o[1])) for o in outs]
    assert sorted(saved) == [0, 1], saved
    assert outs[0][0].splitlines()[-1] == outs[1][0].splitlines()[-1]


def test_builds_of_the_same_native_kernels_at_the_same_time_compile_them_once(monkeypatch, tmp_path):
    """Two builds of one kernel set at once (two FMUs built in parallel): one compiles, for every
    platform, the other waits for the kept objects and copies those it asked for; a build for
    other platforms later compiles nothing."""
    import json
    import threading
    from hammerbit.fmu import native_kernels as nk
    def kept_dir(key):
        (tmp_path / "kept" / key).mkdir(parents=True, exist_ok=True)
        return tmp_path / "kept" / key
    monkeypatch.setattr(nk, "_kept_dir", kept_dir)
    started, release, compiles = threading.Event(), threading.Event(), []

    def compile_once(out_dir, platforms, **kw):
        compiles.append(out_dir)
        started.set()
        release.wait(60)
        for plat in platforms:
            (out_dir / f"kernels_{plat}.o").write_bytes(b"object " + plat.encode())
        return {"layout": {"n": len(compiles)}, "sizes": {plat: len(plat) for plat in platforms}}
    monkeypatch.setattr(nk, "_compile_objects", compile_once)
    results = {}

    def build(name):
        results[name] = nk.build_objects(tmp_path / name, platforms=("linux64",))
    first = threading.Thread(target=build, args=("a",))
    first.start()
    assert started.wait(60)
    second = threading.Thread(target=build, args=("b",))
    second.start()
    second.join(0.5)            # without the lock the second build would be compiling by now
    release.set()
    first.join(60)
    second.join(60)
    assert len(compiles) == 1
    assert results["a"] == results["b"] == {"layout": {"n": 1}, "sizes": {"linux64": 7}}
    assert (tmp_path / "b" / "kernels_linux64.o").read_bytes() == b"object linux64"
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == ["kernels_linux64.o"]
    # the kept entry holds every platform: another selection compiles nothing
    assert nk.build_objects(tmp_path / "c", platforms=("aarch64-linux", "win64")) == {
        "layout": {"n": 1}, "sizes": {"aarch64-linux": 13, "win64": 5}}
    assert len(compiles) == 1
    with pytest.raises(nk.KernelBuildError, match=r"\['win32'\] are out of range: allowed"):
        nk.build_objects(tmp_path / "d", platforms=("linux64", "win32"))
