"""Supply-side forms of the variant simulator: supply_droop (four supply models) and the
supply effects outside the vocabulary (compressor ripple, a supply step).  The nominal supply
is 7 bar (arm2.md); arm2's four valves draw up to ~1.3e-3 kg/s each when wide open and a few
1e-4 kg/s on average while tracking.
"""
from __future__ import annotations

from . import kernel as K
from . import rows as R
from .forms import OUTSIDE, Form

BEATER = "Beater 2007, Pneumatic Drives (Springer)"


def _u(r, lo, hi):
    return float(r.uniform(lo, hi))


def _set(hidden, pairs):
    for row, v in pairs:
        hidden.P_rows[row, 0] = v


def _supply(name, mode, source, summary, draw, keys, scaled=(), inverse=()):
    def apply(col, e, h):
        _set(h, [(R.SU_MODE, float(mode))] + [(row, e[key]) for row, key in keys])
    return Form("supply_droop", name, "supply", source, summary, draw, apply, scaled=scaled, inverse=inverse,
                slots=("supply_state",))


SUPPLY_DROOP = [
    _supply("regulator_reservoir", K.SU_RESERVOIR, BEATER + " (regulator + receiver)",
            "reservoir 20–50 cm³ (isothermal) fed from 7 bar through a regulator orifice of 0.4–0.8e-6 m²",
            lambda r, c: {"regulator_area_m2": _u(r, 0.4e-6, 0.8e-6), "reservoir_volume_m3": _u(r, 2e-5, 5e-5)},
            [(R.SU_A, "regulator_area_m2"), (R.SU_V, "reservoir_volume_m3")], inverse=("regulator_area_m2",)),
    _supply("static_droop", K.SU_STATIC, "ISO 6953-1 regulator flow characteristic (pressure falls with flow)",
            "p_s = 7 bar − R ṁ (ṁ filtered over 5 ms), R 0.5–2e8 Pa s/kg (0.25–1 bar at 5e-4 kg/s)",
            lambda r, c: {"droop_pa_s_kg": _u(r, 0.5e8, 2e8)},
            [(R.SU_R, "droop_pa_s_kg")], scaled=("droop_pa_s_kg",)),
    _supply("proportional_regulator", K.SU_PROPORTIONAL, BEATER + " (pressure regulator with a proportional band)",
            "reservoir 20–50 cm³ fed from 8 bar through an opening ∝ (7 bar − p)/band, full area 0.5–1.5e-6 m², "
            "band 0.3–1 bar",
            lambda r, c: {"regulator_area_m2": _u(r, 0.5e-6, 1.5e-6), "reservoir_volume_m3": _u(r, 2e-5, 5e-5),
                          "band_pa": _u(r, 0.3e5, 1.0e5)},
            [(R.SU_A, "regulator_area_m2"), (R.SU_V, "reservoir_volume_m3"), (R.SU_BAND, "band_pa")],
            scaled=("band_pa",)),
    _supply("compressor_cycling", K.SU_COMPRESSOR, BEATER + " (compressor with a pressure switch)",
            "receiver 0.5–2 L filled at 2–5e-4 kg/s while a switch runs it between 7 bar − band and 7 bar, "
            "band 0.3–0.8 bar; system leak 2–5e-11 kg/(s Pa)",
            lambda r, c: {"receiver_volume_m3": _u(r, 5e-4, 2e-3), "compressor_kg_s": _u(r, 2e-4, 5e-4),
                          "band_pa": _u(r, 0.3e5, 0.8e5), "leak_kg_s_pa": _u(r, 2e-11, 5e-11)},
            [(R.SU_V, "receiver_volume_m3"), (R.SU_QC, "compressor_kg_s"), (R.SU_BAND, "band_pa"),
             (R.SU_LK, "leak_kg_s_pa")], scaled=("band_pa",)),
]


def _step(col, e, h):
    _set(h, [(R.OS_STEP, e["step_pa"])])
    h.supply_step_fraction = e["at_fraction"]


OUTSIDE_SUPPLY = [
    Form(OUTSIDE, "compressor_ripple", "supply", "reciprocating-compressor pulsation reaching the valves",
         "p_s = 7 bar + A sin(2π f t), A 0.1–0.3 bar, f 1–5 Hz",
         lambda r, c: {"amplitude_pa": _u(r, 0.1e5, 0.3e5), "frequency_hz": _u(r, 1.0, 5.0)},
         lambda col, e, h: _set(h, [(R.OS_AMP, e["amplitude_pa"]), (R.OS_HZ, e["frequency_hz"])]),
         scaled=("amplitude_pa",), slots=("ripple",)),
    Form(OUTSIDE, "supply_step", "supply", "a supply pressure step (another consumer switching, a regulator reset)",
         "p_s steps by ±0.3–0.8 bar at 25–75 % of each recording",
         lambda r, c: {"step_pa": float(r.choice([-1.0, 1.0])) * _u(r, 0.3e5, 0.8e5), "at_fraction": _u(r, 0.25, 0.75)},
         _step, scaled=("step_pa",), slots=("step",)),
]

SUPPLY_FORMS = SUPPLY_DROOP + OUTSIDE_SUPPLY
