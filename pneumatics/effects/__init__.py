"""Physical effects a nominal model may leave out (DESIGN.md effect vocabulary).

One family, one module: each holds the family's physical model (forms with unit-carrying
parameters, the numpy law, its sources) and the hooks the simulator (an :class:`EffectSet`
entry), the doctor (its chamber model or its torque balance) and the case makers (parameter
ranges) use; :mod:`.family` is their small base, :mod:`.registry` lists them (``FAMILIES``,
``get_family``), and docs/effects.md shows the table generated from it.  coulomb_friction,
stiction and viscous_friction share ``friction.py`` (terms of one Stribeck curve); the
operators of the valve families are in ``valve_dynamics.py``, the bench cylinder's seal friction
in ``seal_friction.py``.

The simulator switches effects on through :class:`effect_set.EffectSet`
(``Simulation(robot, effects=...)``; ``EffectSet().add("valve_lag", "elbow.b", {"time_constant_s": 0.03})``),
and the mismatch finder tests the same physics as hypotheses (``identification/doctor/valve_arm/hypotheses.py``),
so whatever it finds can be simulated and kept; tests/effects/test_roundtrip.py checks, family
by family, that the two agree.
"""
from .registry import FAMILIES, get_family

__all__ = ["FAMILIES", "VOCABULARY", "get_family"]

#: every family name the doctor can report (DESIGN.md; extend, never rename): the registry's
VOCABULARY = tuple(FAMILIES)
