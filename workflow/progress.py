"""Progress on any terminal or none: a live rich display on a terminal, plain timestamped lines
on stderr otherwise (logs, CI, notebooks), where a live display would print nothing for minutes.

``PNEUMASIM_PROGRESS=plain`` forces the plain lines, ``rich`` the live display, ``none`` silence.
"""
from __future__ import annotations

import os
import sys
import time

MODES = ("rich", "plain", "none")


def progress_mode() -> str:
    """"rich" when stderr is a terminal, else "plain"; PNEUMASIM_PROGRESS overrides."""
    forced = os.environ.get("PNEUMASIM_PROGRESS", "").strip().lower()
    if forced in MODES:
        return forced
    try:
        return "rich" if sys.stderr.isatty() else "plain"
    except (AttributeError, ValueError):  # a closed or replaced stderr
        return "plain"


def plain_line(label: str, msg: str, t0: float) -> str:
    """``13:02:41 +12.3 s doctor: screening hypotheses``: wall clock (UTC) and time since start."""
    return f"{time.strftime('%H:%M:%S', time.gmtime())} +{time.perf_counter() - t0:.1f} s {label}: {msg}"


class Progress:
    """Stages of a long run: ``with Progress("doctor") as p: p.say("calibrating")``.

    On a terminal with ``live=True`` one rich status line is updated in place; on a terminal
    without it each stage is printed by rich; otherwise each stage is a plain line on stderr,
    flushed at once."""

    def __init__(self, label: str, *, live: bool = True, mode: str | None = None):
        self.label, self.live = label, live
        self.mode = mode or progress_mode()
        self.t0 = time.perf_counter()
        self._status = self._console = None

    def __enter__(self) -> "Progress":
        if self.mode == "rich":
            from rich.console import Console

            self._console = Console(stderr=True)
            if self.live:
                self._status = self._console.status(f"{self.label}: starting")
                self._status.start()
        return self

    def say(self, msg: str):
        if self.mode == "plain":
            print(plain_line(self.label, msg, self.t0), file=sys.stderr, flush=True)
        elif self._status is not None:
            self._status.update(f"{self.label}: {msg}")
        elif self._console is not None:
            self._console.print(f"[bold]{self.label}[/bold]: {msg}", highlight=False)

    __call__ = say  # a Progress is itself a progress(msg) callback

    def __exit__(self, *exc):
        if self._status is not None:
            self._status.stop()
        return False
