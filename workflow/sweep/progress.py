"""Progress of a sweep on stderr."""
from __future__ import annotations

import sys
import time

from workflow.progress import plain_line, progress_mode


class ProgressBar:
    """Cases done of total, failed, retries, elapsed and time left: a rich progress bar on a
    terminal, else one plain timestamped line on stderr per finished case (workflow.progress)."""

    def __init__(self, total, done, enabled, label):
        self.total, self.enabled, self.failed, self.retries = total, enabled and total > 0, 0, 0
        self.label, self.done0, self.done = label, done, done
        self.progress = self.task = None
        self.plain = self.enabled and progress_mode() != "rich"
        self.silent = progress_mode() == "none"
        self.t0 = time.perf_counter()

    def _line(self, msg):
        if not self.silent:
            print(plain_line(f"sweep {self.label}", msg, self.t0), file=sys.stderr, flush=True)

    def __enter__(self):
        if self.plain:
            self._line(f"{self.total} cases" + (f", {self.done0} resumed" if self.done0 else ""))
        elif self.enabled:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                     TextColumn("failed {task.fields[failed]}  retries {task.fields[retries]}"),
                                     TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(),
                                     console=Console(stderr=True))
            self.progress.start()
            desc = f"sweep {self.label}" + (f" ({self.done0} resumed)" if self.done0 else "")
            self.task = self.progress.add_task(desc, total=self.total, completed=self.done0, failed=0, retries=0)
        return self

    def advance(self, failed: bool):
        self.failed += failed
        self.done += 1
        if self.plain:
            ran, left = self.done - self.done0, self.total - self.done
            eta = (time.perf_counter() - self.t0) / ran * left
            self._line(f"{self.done}/{self.total} done, {self.failed} failed, {self.retries} retries"
                       + (f", ~{eta:.0f} s left" if left else ""))
        if self.progress:
            self.progress.update(self.task, advance=1, failed=self.failed)

    def retried(self):
        self.retries += 1
        if self.progress:
            self.progress.update(self.task, retries=self.retries)

    def refresh(self):
        if self.progress:
            self.progress.refresh()

    def __exit__(self, *exc):
        if self.progress:
            self.progress.stop()
        return False
