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


def summary_head(report: dict, seconds: float | None = None) -> list[str]:
    """The first two lines of a doctor's ten-second summary: the model, how much data was fitted
    and held out (and the run's wall time, if given), the verdict and its detail."""
    d = report["diagnostics"]
    took = f", {seconds:.0f} s" if seconds is not None else ""
    return [f"pneumasim doctor — {report['model']}: {d['train_seconds']:.0f} s fitted, "
            f"{d['heldout_seconds']:.0f} s held out{took}",
            f"verdict: {report['verdict'].replace('_', ' ')} — {report['verdict_detail']}"]


def finding_line(i: int, finding: dict, what_tells_apart: str) -> str:
    """``  i. effect at place: parameter = value ± error, ...`` and the families these
    ``what_tells_apart`` ("data", "sensors") cannot separate from it."""
    where = " ".join(f"{k} {v}" for k, v in finding["where"].items())
    par = ", ".join(with_error(k, v, 4, 2) for k, v in finding["parameters"].items())
    alt = (f"  (or {', '.join(finding['alternatives'])}: not separable with these {what_tells_apart})"
           if finding["alternatives"] else "")
    return f"  {i}. {finding['effect']} at {where}: {par}{alt}"


def with_error(name: str, v: dict, digits: int = 3, error_digits: int = 1) -> str:
    """``name = value ± stderr`` of a reported parameter ({"value", "stderr"}); a parameter
    without an error bar (a level the calibration shares, a bound it reached) says so."""
    se = v.get("stderr")
    err = f" ± {se:.{error_digits}g}" if se is not None and np.isfinite(se) else " (no error bar)"
    return f"{name} = {v['value']:.{digits}g}{err}"
