"""How a command ends when it is stopped: Ctrl-C (SIGINT) or a job scheduler's SIGTERM.

The work is unwound as for any exception (every output folder discards its staging folder, so
the previous results stay as they were), one line says so on stderr, and the process then ends
*killed by the signal it received* — the Unix convention a calling shell, ``make`` or a batch
script relies on to stop too (exit status 130 for Ctrl-C, 143 for SIGTERM, in a shell).

Why not ``sys.exit(1)``: CPython itself ends by SIGINT whenever a KeyboardInterrupt reached the
top of *any* nested ``PyRun_*`` call, which pybind11 extension modules (MuJoCo, SciPy's HiGHS)
make while they initialise; a Ctrl-C landing during such an import made the same program end
with status 1 on some runs and by SIGINT on others. Ending by the signal ourselves makes the
outcome one. The same import turns the KeyboardInterrupt into ``ImportError: initialization
failed``; the handler below records the signal, so that error is recognised as the stop it is
instead of being printed as a traceback. And where Python runs the handler inside a callback
whose exceptions it ignores (a weakref callback of the import system), the KeyboardInterrupt is
lost; :func:`raise_if_stopped`, called before any results are swapped in, raises it again.
"""
from __future__ import annotations

import atexit
import os
import signal
import sys
import threading
from contextlib import contextmanager

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class _Stop:
    received: int | None = None


def _on_stop(signum, frame):
    _Stop.received = signum
    raise KeyboardInterrupt


def stop_received() -> bool:
    """Whether SIGINT or SIGTERM arrived inside :func:`stops_cleanly`'s block."""
    return _Stop.received is not None


def raise_if_stopped():
    """Raise KeyboardInterrupt if a stop arrived whose KeyboardInterrupt Python swallowed (see the
    module's docstring): called before a run's results replace the previous ones."""
    if stop_received():
        raise KeyboardInterrupt


@contextmanager
def stops_cleanly(prefix: str):
    """Run the block; if SIGINT or SIGTERM stops it, print ``<prefix>interrupted; the previous
    results are unchanged`` and end the process by that signal (after the block's own clean-up
    and the interpreter's exit handlers). Outside the main thread (a caller's worker) signals
    cannot be handled here: a KeyboardInterrupt then prints the line and exits with status 1."""
    if threading.current_thread() is not threading.main_thread():
        try:
            yield
        except KeyboardInterrupt:
            sys.exit(f"{prefix}interrupted; the previous results are unchanged")
        return
    # a SIGINT ignored at start (a background job of a shell without job control) stays ignored
    handled = [s for s in STOP_SIGNALS if signal.getsignal(s) is not signal.SIG_IGN]
    previous = {s: signal.signal(s, _on_stop) for s in handled}
    _Stop.received = None
    try:
        yield
        raise_if_stopped()
    except BaseException as e:  # noqa: BLE001 - any exception raised while a stop unwinds is the stop
        if _Stop.received is None and not isinstance(e, KeyboardInterrupt):
            raise
        print(f"{prefix}interrupted; the previous results are unchanged", file=sys.stderr)
        _end_by(_Stop.received or signal.SIGINT)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _end_by(signum: int):
    """End the process killed by ``signum``, as an unhandled Ctrl-C ends CPython: exit handlers
    first (Rerun, multiprocessing and logging flush there), then the default action."""
    atexit._run_exitfuncs()  # what atexit.register installed, run now as a normal exit would run it
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nothing more to tell anyone
            pass
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, [signum])  # delivered here at the latest
    os._exit(128 + signum)  # not reached: the default action of SIGINT and SIGTERM ends us
