"""The mismatch finder for bench rigs (``pneumasim doctor --model bench_chamber|bench_cylinder``).

Same report contract as :mod:`identification.doctor.valve_arm.diagnose` (DESIGN.md "The mismatch finder"), for
test benches whose physics is small enough to fit every hypothesis outright:

* **bench_chamber** (a chamber charged, then shut): the nominal model holds the pressure.
  Hypotheses ``external_leak`` (isothermal laminar leak to the room, closed form),
  ``heat_transfer`` (the gas, heated by the charging, cools to the wall: closed form) and both
  together (leak + finite gas-wall heat exchange, energy balance of Richer & Hurmuzlu 2000,
  integrated by RK4).  Fitted by nonlinear least squares on the first part, judged by how
  well each *extrapolates* over the held-out part: a leak keeps falling towards room
  pressure, a thermal relaxation levels off above it.  When both extrapolate alike, the
  verdict says they cannot be told apart.
* **bench_cylinder** (the rod moved along a recorded displacement, cap chamber at a regulated
  pressure, load cell on the rod): nominal force p_g A.  Hypotheses: Coulomb friction
  (symmetric or per direction), viscous friction, a load-cell offset, and with recordings at
  several pressures Coulomb friction growing with pressure — all linear in their parameters,
  fitted by least squares with standard errors.  A symmetric friction plus a load-cell offset
  equals an asymmetric friction; the report says so instead of picking one.
"""
from __future__ import annotations

from pneumatics.bench.model import BenchChamberCfg, load_bench
from pneumatics.errors import RecordingError
from pneumatics.recording import Recording

from .chamber_fit import diagnose_chamber
from .common import HOLDOUT
from .cylinder_fit import diagnose_cylinder, velocity

__all__ = ["diagnose_bench", "velocity"]


def diagnose_bench(model: str, recordings: list[Recording], holdouts: list[Recording] = (),
                   holdout_fraction: float = HOLDOUT, progress=None) -> dict:
    """Diagnose bench recordings of ``model``; returns the report dict (see report.write).
    ``progress(msg)``, if given, is told each stage."""
    say = progress or (lambda msg: None)
    if not recordings:
        raise RecordingError("bench doctor: no recordings given")
    cfg = load_bench(model)
    for r in [*recordings, *holdouts]:
        if r.meta.get("model") not in (None, model):
            raise RecordingError(f"{r.source}: recorded for model {r.meta['model']!r} (sidecar), "
                                 f"diagnosed as {model!r}")
    if isinstance(cfg, BenchChamberCfg):
        say("fitting the chamber model (orifice areas, heat transfer, leaks) and checking it on held-out data")
        return diagnose_chamber(model, cfg, recordings, list(holdouts), holdout_fraction)
    say("fitting the cylinder's friction models and checking them on held-out data")
    return diagnose_cylinder(model, cfg, recordings, list(holdouts), holdout_fraction)
