"""Drawing a figure in a second process while this one computes what it shows.

Importing matplotlib and drawing a four-panel figure cost a warm ``hammerbit
simulate --plot`` about as much as importing numba, loading the compiled
kernels and running the scene.  On a machine with two cores or more the two
halves need not wait for each other: :func:`start` launches a worker
(``python -m hammerbit.scene.figure_worker``) that imports matplotlib while this
process loads the solver; :meth:`FigureWorker.draw` sends it a drawing
function and its data (pickled); :meth:`FigureWorker.result` waits for the
file.

The worker draws exactly what the same function draws in this process (same
code, same data, same matplotlib), so the file is the same byte for byte.  An
error while drawing (an unsupported format, a disk that is full) comes back
as the same exception, raised here.  If the worker cannot be started or dies
without an answer, :meth:`FigureWorker.formats` and :meth:`FigureWorker.result`
return ``None`` and the caller draws in this process instead: the worker
saves time, it never decides an outcome.

``HAMMERBIT_FIGURE_WORKER=0`` turns it off (every figure is drawn in this
process); it is also off on a single-core machine and in a process that has
imported matplotlib already (a notebook, a test session).

Protocol (pickle frames): the worker writes ``("formats", set)`` once
matplotlib is imported; it reads ``("draw", func, args, kwargs)`` or end of
input (nothing to draw), and answers ``("done", value)`` or ``("error",
exception)``.  Anything the drawing code prints goes to stderr, never into the
protocol stream.
"""
from __future__ import annotations

import os
import pickle
import subprocess
import sys
import traceback

__all__ = ["FigureWorker", "start", "figure_formats", "ENV"]

#: environment variable that turns the worker off ("0")
ENV = "HAMMERBIT_FIGURE_WORKER"


def figure_formats() -> set:
    """File extensions matplotlib can save (png, pdf, svg, ...)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415
    from matplotlib.figure import Figure  # noqa: PLC0415
    return set(FigureCanvasAgg(Figure()).get_supported_filetypes())


def enabled() -> bool:
    """True where a worker can save time: not turned off, more than one core, a Python executable,
    and matplotlib not imported in this process yet (drawing here then costs no import)."""
    if os.environ.get(ENV, "1").strip() in ("0", "false", "no", "off"):
        return False
    if (os.cpu_count() or 1) < 2 or "matplotlib" in sys.modules:
        return False
    return bool(sys.executable)


class FigureWorker:
    """A running worker process (see the module docs); use :func:`start` to get one."""

    def __init__(self, proc: subprocess.Popen):
        self._proc = proc
        self._formats = None
        self._sent = False
        self._failed = False

    def _read(self):
        """The next message, or None if the worker ended without one."""
        try:
            return pickle.load(self._proc.stdout)
        except Exception:  # noqa: BLE001 -- EOF, a truncated frame: the worker is gone
            self._failed = True
            return None

    def formats(self):
        """The file extensions the worker's matplotlib can save (waits for it), or None if it failed."""
        if self._formats is None and not self._failed:
            msg = self._read()
            if msg is not None and msg[0] == "formats":
                self._formats = set(msg[1])
            else:
                self._failed = True
        return None if self._failed else self._formats

    def draw(self, func, *args, **kwargs) -> bool:
        """Ask the worker to call ``func(*args, **kwargs)``; False if it cannot (draw here instead).

        ``func`` must be importable by name in a fresh process, and ``args``
        picklable.
        """
        if self.formats() is None:
            return False
        try:
            pickle.dump(("draw", func, args, kwargs), self._proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self._proc.stdin.close()
        except (OSError, pickle.PicklingError, AttributeError, TypeError):
            self._failed = True
            return False
        self._sent = True
        return True

    def result(self):
        """What the drawing returned (waits), or None if the worker failed before answering.

        Raises the drawing's own exception if it raised one.
        """
        if not self._sent or self._failed:
            return None
        msg = self._read()
        self.close()
        if msg is None:
            return None
        if msg[0] == "error":
            raise msg[1]
        return msg[1]

    def abort(self) -> None:
        """Stop the worker now, drawing or not (the caller was interrupted or failed)."""
        if self._proc.poll() is None:
            self._proc.terminate()
        self._sent = False
        self.close()

    def close(self) -> None:
        """End the worker: it exits at end of input once it has answered, else it is stopped; idempotent."""
        p = self._proc
        if not self._sent and p.poll() is None:
            p.terminate()  # nothing to draw (the caller failed first): do not wait for its imports
        for f in (p.stdin, p.stdout):
            try:
                f.close()
            except OSError:
                pass
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:  # pragma: no cover -- a hung worker
            p.kill()
            p.wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def start():
    """A :class:`FigureWorker` importing matplotlib in the background, or None where it is off."""
    if not enabled():
        return None
    try:
        # its own process group: a Ctrl-C in the terminal goes to the caller alone, which stops the
        # worker (FigureWorker.abort) and reports it once; the worker also ends at the end of its input
        group = {"process_group": 0} if os.name == "posix" else {}
        proc = subprocess.Popen([sys.executable, "-m", __name__], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=None, **group)
    except OSError:
        return None
    return FigureWorker(proc)


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else a RuntimeError with its type and message."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001
        return RuntimeError(f"{type(exc).__name__}: {exc}")


def _main() -> int:
    """The worker: announce the formats, draw once, answer."""
    out = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())  # stray prints go to stderr
    inp = sys.stdin.buffer

    def send(msg):
        pickle.dump(msg, out, protocol=pickle.HIGHEST_PROTOCOL)
        out.flush()

    try:
        import matplotlib  # noqa: PLC0415
        matplotlib.use("Agg")
        formats = sorted(figure_formats())
    except Exception:  # noqa: BLE001 -- the caller draws in its own process and reports the error
        if os.environ.get("HAMMERBIT_DEBUG"):
            traceback.print_exc()
        return 1
    send(("formats", formats))
    try:
        msg = pickle.load(inp)
    except EOFError:
        return 0  # nothing to draw
    try:
        _, func, args, kwargs = msg
        send(("done", func(*args, **kwargs)))
    except Exception as exc:  # noqa: BLE001 -- sent back and raised in the caller
        if os.environ.get("HAMMERBIT_DEBUG"):
            traceback.print_exc()
        send(("error", _portable(exc)))
    return 0


if __name__ == "__main__":
    try:
        code = _main()
    except KeyboardInterrupt:
        code = 130
    except BrokenPipeError:
        code = 0
    # nothing to tear down (the figure is written and closed): skip the interpreter's finalisation,
    # which the caller would otherwise wait for
    sys.stderr.flush()
    os._exit(code)
