"""Ctrl-C in the command line: one line on stderr, exit code 130, and no output file changed.

Three pieces, used by :func:`hammerbit.cli.common.run_command` around every command:

* :func:`install_early_exit` -- from the first statement of the ``hammerbit``
  executable until a command starts (imports, argument parsing), a Ctrl-C
  prints the one line and ends the process with 130 at once: nothing has been
  written and no process started yet.
* :func:`interrupt_or_exit` -- while a command runs, a Ctrl-C raises
  ``KeyboardInterrupt`` in the main thread, so that every ``finally`` runs
  (worker processes are closed, staged files removed).  Where raising would
  be garbled (inside numba's or llvmlite's code, whose ctypes callbacks print
  "Exception ignored" instead of propagating), the interrupt is kept pending
  and delivered again every :data:`RETRY_S` until it lands outside them, and
  at the latest when the block ends: an interrupt is never lost.  If the
  process is still alive :data:`INTERRUPT_GRACE_S` after the Ctrl-C (a long
  compile, a foreign FMU host that turns the exception into a failed step),
  it removes its staged files, prints the line and exits with 130.
* :class:`Staging` -- every output file is written to a temporary file in
  its own directory (:func:`staged`) and renamed onto its name only when the
  command has finished (:meth:`Staging.commit`); an interrupted or failed
  command removes its temporary files, so a file that existed before is kept
  unchanged and no partial file is left.  Once the command has committed, a
  Ctrl-C is ignored: the command is complete.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import uuid

__all__ = ["EXIT_INTERRUPTED", "INTERRUPT_GRACE_S", "RETRY_S", "install_early_exit", "interrupt_or_exit",
           "end_interrupted",
           "Staging", "staged", "say_interrupted"]

EXIT_INTERRUPTED = 130
#: Seconds a Ctrl-C may take to end a command before :func:`interrupt_or_exit` ends the process.
INTERRUPT_GRACE_S = 2.0
#: Seconds between deliveries of a Ctrl-C kept pending (it arrived inside numba's compiler).
RETRY_S = 0.05

#: The stagings of the commands running in this process (innermost last).
_STAGINGS: list = []


def say_interrupted(prog: str = "hammerbit") -> None:
    """The one line of an interrupted command."""
    print(f"{prog}: interrupted", file=sys.stderr, flush=True)


def end_interrupted() -> None:
    """End the process with 130 now: staged files removed, the compile helper stopped, streams flushed."""
    for st in list(_STAGINGS):
        st.discard()
    helper = sys.modules.get("hammerbit.model.numba_compile_ahead")
    if helper is not None:
        with contextlib.suppress(Exception):
            helper.finish()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(EXIT_INTERRUPTED)


def _exit_now(prog: str) -> None:
    """The one line, then :func:`end_interrupted`."""
    say_interrupted(prog)
    end_interrupted()


def install_early_exit(prog: str = "hammerbit") -> None:
    """A Ctrl-C before a command starts ends the process at once with the one line and 130."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, lambda signum, frame: _exit_now(prog))


class _Guard:
    """The SIGINT handler of one :func:`interrupt_or_exit` block."""

    def __init__(self, prog: str, grace_s: float, always: bool):
        self.prog, self.grace_s, self.always = prog, grace_s, always
        self.pending = False      # a Ctrl-C arrived and has not been raised yet
        self.raised = False
        self.done = False         # the command is complete: a Ctrl-C is ignored
        self.closed = False
        self._timer = None

    def handler(self, signum, frame):
        if self.done or self.closed:
            return
        self.pending = True
        if _in_compiler(frame):
            self._arm()
            self._redeliver()
            return
        if self.always:
            self._arm()
        self.raised = True
        raise KeyboardInterrupt

    def finish(self) -> None:
        """The command is complete: from now on a Ctrl-C is ignored (unless one is pending)."""
        if self.pending and not self.raised:
            self.raised = True
            raise KeyboardInterrupt
        self.done = True

    def _arm(self) -> None:
        if self._timer is None:
            self._timer = threading.Timer(self.grace_s, _exit_now, args=(self.prog,))
            self._timer.daemon = True
            self._timer.start()

    def _redeliver(self) -> None:
        def loop():
            while True:
                threading.Event().wait(RETRY_S)
                if self.raised or self.closed:
                    return
                # a real signal to the main thread: it also wakes a blocking wait there
                signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)
        if not getattr(self, "_loop", None):
            self._loop = threading.Thread(target=loop, name="hammerbit-interrupt", daemon=True)
            self._loop.start()

    def close(self) -> None:
        self.closed = True
        if self._timer is not None:
            self._timer.cancel()


@contextlib.contextmanager
def interrupt_or_exit(grace_s: float = INTERRUPT_GRACE_S, prog: str = "hammerbit", *, always: bool = True):
    """Ctrl-C raises ``KeyboardInterrupt`` (kept pending inside numba's compiler, never lost); where
    the process is still alive ``grace_s`` later, it ends with the one line and exit code 130.

    With ``always`` (around a foreign FMU host, which may swallow the exception)
    the timer is armed on every Ctrl-C; otherwise only on one kept pending.
    The block yields its guard: ``guard.finish()`` marks the command complete.
    """
    if threading.current_thread() is not threading.main_thread():
        yield None
        return
    guard = _Guard(prog, grace_s, always)
    old = signal.signal(signal.SIGINT, guard.handler)
    try:
        yield guard
        if guard.pending and not guard.raised:
            guard.raised = True
            raise KeyboardInterrupt
    except Exception as exc:
        if guard.pending:
            # the Ctrl-C surfaced as another error: a foreign host (an FMU's instantiate, an
            # extension module) caught the KeyboardInterrupt and failed instead
            raise KeyboardInterrupt from exc
        raise
    finally:
        signal.signal(signal.SIGINT, old)
        guard.close()


_COMPILER_DIRS = (os.sep + "numba" + os.sep, os.sep + "llvmlite" + os.sep)


def _in_compiler(frame) -> bool:
    """True if ``frame`` or a caller runs numba's or llvmlite's code."""
    while frame is not None:
        name = frame.f_code.co_filename
        if any(d in name for d in _COMPILER_DIRS):
            return True
        frame = frame.f_back
    return False


# ---------------------------------------------------------------------------
# output files: written beside their name, renamed when the command is complete
# ---------------------------------------------------------------------------
class Staging:
    """The output files of one command: temporary names now, their own names at :meth:`commit`."""

    def __init__(self):
        self._files: dict = {}          # final absolute path -> temporary path

    def __enter__(self) -> "Staging":
        _STAGINGS.append(self)
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is not None:
                self.discard()
        finally:
            if self in _STAGINGS:
                _STAGINGS.remove(self)

    def path(self, final) -> str:
        """The temporary file to write instead of ``final``: same directory, same extension."""
        full = os.path.abspath(os.path.expanduser(str(final)))
        if full in self._files:
            return self._files[full]
        folder, name = os.path.split(full)
        stem, ext = os.path.splitext(name)
        tmp = os.path.join(folder, f".{stem}.{uuid.uuid4().hex[:8]}.part{ext}")
        self._files[full] = tmp
        return tmp

    def commit(self) -> None:
        """Rename every written temporary file onto its name (one ``os.replace`` each)."""
        for final, tmp in list(self._files.items()):
            if os.path.exists(tmp):
                os.replace(tmp, final)
            del self._files[final]

    def discard(self) -> None:
        """Remove every temporary file (an interrupted or failed command)."""
        for final, tmp in list(self._files.items()):
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            self._files.pop(final, None)


def staged(path):
    """Where to write the output ``path`` now: a temporary file renamed onto ``path`` when the
    running command completes; ``path`` itself outside a command (a library call).  None stays None."""
    if path is None or not _STAGINGS:
        return path
    return _STAGINGS[-1].path(path)
