"""Calling a compiled numba function without the dispatcher's typing of its arguments.

A numba dispatcher types every argument on every call to pick the compiled
version (for a kernel with many arguments, about as long as a small kernel
runs).  A caller that passes arguments of the same types at every call, as
a stepping loop does, can look the compiled version up once and call its
entry point directly.
"""

__all__ = ["entry_point"]


def entry_point(dispatcher, args):
    """The compiled function of the numba ``dispatcher`` for ``args``, or the dispatcher.

    Called with arguments of the same types as ``args`` (the same arrays, or
    arrays of the same dtype, dimensions, layout and writability), it skips the
    dispatcher's typing.  The dispatcher itself when it has no compiled
    version for these types yet (call it once first).
    """
    try:
        from numba import typeof  # noqa: PLC0415
        return dispatcher.overloads[tuple(typeof(a) for a in args)].entry_point
    except Exception:  # noqa: BLE001 -- not compiled for these types (or another numba): dispatch
        return dispatcher
