"""Progress of a sweep on stderr."""
from __future__ import annotations


class ProgressBar:
    """A rich progress bar: cases done of total, failed, retries, elapsed and time left."""

    def __init__(self, total, done, enabled, label):
        self.total, self.enabled, self.failed, self.retries = total, enabled and total > 0, 0, 0
        self.label, self.done0 = label, done
        self.progress = self.task = None

    def __enter__(self):
        if self.enabled:
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
