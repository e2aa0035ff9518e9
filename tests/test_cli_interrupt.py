"""Ctrl-C in every command, at any moment from 0.1 s on: exit 130, one line on stderr, no output changed.

The specification (docs/cli.md, "Exit codes" and "Output files"): a SIGINT
to the ``hammerbit`` process ends it with exit code 130 and the one line
``hammerbit: interrupted`` on stderr (no warning, no traceback); a file that
existed before is unchanged, and no new file is left in the output's directory.

* In process (fast): the staging of outputs through ``run_command``, and an
  interrupt that arrives inside numba's compiler is kept and raised, never lost.
* Real processes: a few (command, delay) pairs in the fast set; every command
  at every delay of :data:`SLOW_DELAYS` in the slow set.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

#: a hang guard only (the command must end after SIGINT); not a timing goal
GUARD_S = 180.0
#: delays [s] from the start of the process to its SIGINT, in the slow loop
SLOW_DELAYS = (0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.0)
FIELD = ["--string", "field-2200m"]
#: every command, run long enough to be running at every delay: argv and its output files
#: (the first of which exists before the run, with content that must survive)
COMMANDS = {
    "simulate": (["simulate", "--periods", "90000", "--csv", "out.csv", "--plot", "out.png"],
                 ["out.png", "out.csv"]),
    "modes": (["modes", *FIELD, "--fmax", "2000", "--exact", "--csv", "out.csv"], ["out.csv"]),
    "check": (["check", *FIELD, "--frequency", "20", "--range", "0", "2000", "--plot", "out.png"], ["out.png"]),
    "cosim": (["cosim", *FIELD, "--stop", "200", "--out", "out.csv"], ["out.csv"]),
    "sweep": (["sweep", *FIELD, "--frequencies", "15", "30", "50", "--workers", "1", "--csv", "out.csv",
               "--plot", "out.png"], ["out.csv", "out.png"]),
    "bifurcation": (["bifurcation", "--range", "0", "0.25", "--num", "4000", "--workers", "2", "--out", "out.png",
                     "--csv", "out.csv"], ["out.png", "out.csv"]),
    "map": (["map", "--axis", "a=0.05:0.25:400", "--axis", "eta=0.6:1.4:400", "--workers", "2", "--out", "out.nc",
             "--plot", "out.png"], ["out.nc", "out.png"]),
    "optimize": (["optimize", "--grid", "200", "--workers", "1", "--json"], []),
    "fmu build": (["fmu", "build", "--out", "out.fmu"], ["out.fmu"]),
    "fmu build-string": (["fmu", "build-string", *FIELD, "--out", "out.fmu"], ["out.fmu"]),
    "ssp build": (["ssp", "build", "--string", "lab", "--out", "out.ssp"], ["out.ssp"]),
}
OLD = b"a file that existed before the run\n"


def _hammerbit():
    exe = os.path.join(os.path.dirname(sys.executable), "hammerbit")
    return [exe] if os.path.exists(exe) else [sys.executable, "-m", "hammerbit"]


def _listing(folder):
    return sorted(os.listdir(folder))


def _cpu_s(pid: int) -> float:
    """CPU time [s] the process has had (user + system), 0 if it cannot be read."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return 0.0


#: a delay counts from the start of the process, but not before it has had this much CPU time: on a
#: loaded machine the interpreter's own start-up (before the first statement of ``hammerbit``, where
#: nothing can catch a signal) can take longer than 0.1 s of wall time; it takes about 0.05 s of CPU
STARTUP_CPU_S = 0.1


def _wait_for(p, t0: float, delay: float) -> None:
    """Until ``delay`` s after ``t0`` and at least :data:`STARTUP_CPU_S` of CPU in ``p`` (or its end)."""
    while p.poll() is None and (time.monotonic() < t0 + delay or
                                (os.path.exists("/proc/self/stat") and _cpu_s(p.pid) < STARTUP_CPU_S)):
        time.sleep(0.005)


def interrupt_each(runs, base):
    """Start every ``(command name, delay)`` of ``runs`` at once, each in its own directory under
    ``base``, SIGINT each ``delay`` s after its own start (:func:`_wait_for`); check every promise of
    the module doc.  Returns the names of the runs that had ended before their signal."""
    started = []
    for k, (name, delay) in enumerate(runs):
        argv, outputs = COMMANDS[name]
        folder = base / f"{k}"
        folder.mkdir()
        if outputs:
            (folder / outputs[0]).write_bytes(OLD)
        before = _listing(folder)
        p = subprocess.Popen(_hammerbit() + argv, cwd=folder, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             env=dict(os.environ, MPLBACKEND="Agg"))
        started.append((name, delay, folder, outputs, before, p, time.monotonic()))
    too_late = []
    for name, delay, folder, outputs, before, p, t0 in sorted(started, key=lambda s: s[6] + s[1]):
        _wait_for(p, t0, delay)
        if p.poll() is not None:
            too_late.append(name)
        else:
            p.send_signal(signal.SIGINT)
    for name, delay, folder, outputs, before, p, t0 in started:
        try:
            _, err = p.communicate(timeout=GUARD_S)
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate()
            pytest.fail(f"{name}: still running {GUARD_S:g} s after SIGINT at {delay} s")
        if name in too_late:
            continue
        err = err.decode(errors="replace")
        where = f"{name}, SIGINT at {delay} s"
        assert p.returncode == 130, (where, p.returncode, err[-3000:])
        assert err.splitlines() == ["hammerbit: interrupted"], (where, err[-3000:])
        assert _listing(folder) == before, (where, "files changed", before, _listing(folder))
        if outputs:
            assert (folder / outputs[0]).read_bytes() == OLD, (where, "the existing output was changed")
    return too_late


# --------------------------------------------------------------------------- in process
def test_a_completed_command_renames_its_outputs_and_an_interrupted_one_leaves_none(tmp_path, capsys):
    """run_command's staging: the command writes to a temporary file beside the output; on return
    the output is replaced; on KeyboardInterrupt (exit 130) or an error the old file is unchanged and
    no other file is left."""
    from hammerbit.cli.common import run_command, staged
    out = tmp_path / "out.csv"

    def writes_then(outcome):
        def func(args):
            with open(staged(str(out)), "w") as fh:
                fh.write("new\n")
            assert not out.read_text() == "new\n"       # not yet on its name
            if outcome is not None:
                raise outcome
            return 0
        return func

    for outcome, code in ((KeyboardInterrupt(), 130), (RuntimeError("boom"), 1)):
        out.write_text("old\n")
        assert run_command(writes_then(outcome), None) == code
        assert out.read_text() == "old\n" and _listing(tmp_path) == ["out.csv"]
    assert capsys.readouterr().err.splitlines() == ["hammerbit: interrupted", "hammerbit: error: RuntimeError: boom"]
    assert run_command(writes_then(None), None) == 0
    assert out.read_text() == "new\n" and _listing(tmp_path) == ["out.csv"]


def _in_fake_compiler(fn):
    """``fn()`` called from a frame whose file is in a ``numba`` directory (where the handler must
    not raise: numba's ctypes callbacks would print "Exception ignored" and drop it)."""
    code = compile("def call(fn):\n    fn()\n    return 1\n", os.path.join(os.sep, "x", "numba", "core.py"), "exec")
    ns = {}
    exec(code, ns)
    return ns["call"](fn)


def _sigint_self():
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.01)                         # the handler runs here, inside the "compiler"


def test_a_ctrl_c_inside_the_compiler_is_raised_as_soon_as_the_compiler_is_left():
    from hammerbit.cli.interrupt import RETRY_S, interrupt_or_exit
    t0 = None
    with pytest.raises(KeyboardInterrupt):
        with interrupt_or_exit(grace_s=60.0, always=False):
            assert _in_fake_compiler(_sigint_self) == 1     # not raised inside
            t0 = time.monotonic()
            time.sleep(30.0)                                # delivered again: raised here
    assert t0 is not None and time.monotonic() - t0 < 10.0 + 100 * RETRY_S


def test_a_ctrl_c_inside_the_compiler_is_raised_at_the_end_of_the_block():
    """The block ends right after the compiler: the interrupt is raised there, not lost (the
    command would otherwise finish, write its files and exit 0)."""
    from hammerbit.cli.interrupt import interrupt_or_exit
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with interrupt_or_exit(grace_s=60.0, always=False):
            _in_fake_compiler(_sigint_self)
            reached.append(True)
    assert reached == [True]


def test_a_ctrl_c_that_a_host_turns_into_another_error_is_raised_as_the_interrupt():
    """A foreign host (pythonfmu's instantiate under fmpy) catches the KeyboardInterrupt and fails
    with its own error: the block raises the interrupt (exit 130), not the host's error (exit 1)."""
    from hammerbit.cli.interrupt import interrupt_or_exit

    def host_instantiate():
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
        except KeyboardInterrupt:
            raise RuntimeError("Failed to instantiate model") from None

    with pytest.raises(KeyboardInterrupt) as got:
        with interrupt_or_exit(grace_s=60.0, always=False):
            host_instantiate()
    assert "Failed to instantiate model" in str(got.value.__cause__)
    # without a Ctrl-C the host's own error goes through unchanged
    with pytest.raises(ValueError):
        with interrupt_or_exit(grace_s=60.0, always=False):
            raise ValueError("a host's own error")


def test_after_the_command_completed_a_ctrl_c_is_ignored():
    from hammerbit.cli.interrupt import interrupt_or_exit
    with interrupt_or_exit(grace_s=60.0, always=False) as guard:
        guard.finish()
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)


# --------------------------------------------------------------------------- real processes
def test_ctrl_c_early_and_in_a_cluster_map(tmp_path):
    """Fast representatives: simulate at 0.1 s (the imports) and map on 2 local workers at 1.5 s."""
    too_late = interrupt_each([("simulate", 0.1), ("map", 1.5)], tmp_path)
    assert not too_late, too_late


@pytest.mark.soak
@pytest.mark.slow
@pytest.mark.parametrize("delay", SLOW_DELAYS)
def test_ctrl_c_in_every_command_at_every_delay(delay, tmp_path):
    too_late = interrupt_each([(name, delay) for name in COMMANDS], tmp_path)
    assert not too_late, f"ended before the signal at {delay} s: {too_late} (make them longer)"
