"""The row checks every recording reader applies, whatever the file format: values finite,
at least two rows, time strictly increasing; errors name the file, the row (or line) and the
column."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import RecordingError


def check_rows(path: Path, header: list[str], data: np.ndarray, first: int = 1, word: str = "row"):
    """Raise a RecordingError for the first bad value of ``data`` (rows x ``header`` columns).
    Row i of ``data`` is called ``word`` i + ``first`` (a CSV's line 2 is its first data row)."""
    bad = ~np.isfinite(data)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise RecordingError(f"{path}: {word} {i + first}, column {header[j]!r} is {data[i, j]} "
                             f"({int(bad.sum())} non-finite value(s) in all); clean or cut the recording")
    t = data[:, header.index("time")]
    if t.size < 2:
        raise RecordingError(f"{path}: needs at least 2 rows, has {t.size}")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0))
        raise RecordingError(f"{path}: time is not strictly increasing at {word} {i + 1 + first} "
                             f"({t[i]:g} s then {t[i + 1]:g} s)")
