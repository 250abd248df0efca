"""Report pieces every doctor shares: report dicts made JSON-safe, matplotlib without a display,
figures saved atomically."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pneumatics.io import atomic_save


def jsonable(x):
    """``x`` with numpy scalars made Python numbers, non-finite floats made None (JSON has no
    NaN) and dict keys that start with ``_`` (a report's private plot data) left out."""
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items() if not k.startswith("_")}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x


def pyplot():
    """matplotlib.pyplot on the Agg backend (doctors run without a display)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def save_figure(fig, path: Path, dpi: int = 100):
    """Write ``fig`` to ``path`` (tight bounding box) atomically, then close it."""
    atomic_save(path, lambda tmp: fig.savefig(tmp, dpi=dpi, bbox_inches="tight"))
    pyplot().close(fig)
