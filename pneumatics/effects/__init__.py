"""Physical effects a nominal model may leave out (DESIGN.md effect vocabulary).

Each effect is a small physical model with named, unit-carrying parameters.  The simulator
switches them on through :class:`effect_set.EffectSet` (``Simulation(robot, effects=...)``),
and the mismatch finder tests the same physics as hypotheses
(``identification/hypotheses.py``), so whatever it finds can be simulated and kept.

| family | physics | simulator | doctor |
| --- | --- | --- | --- |
| coulomb_friction, stiction, viscous_friction | Coulomb + Stribeck + viscous torque (`friction.py`) | kernel, qfrc_applied | yes |
| valve_leak | spool open both ways near null: extra Gaussian area, alike on both lands or not (`valve_leak_exhaust_m2`) | valve areas | yes |
| external_leak | orifice from a chamber to the room, or a laminar capillary (`external_leak.laminar_flow`; `chamber.leak_flows`) | kernel | yes (both forms) |
| piston_leak | orifice or laminar gap between chambers a and b, conserving the cylinder's air | kernel | yes (both forms) |
| valve_hysteresis | play operator between command and spool (`valve_dynamics.play`) | at each command | yes |
| valve_lag | first-order lag of the spool (`valve_dynamics.first_order_lag`) | spool stepped per physics step | yes |
| line_dynamics | tube between valve and chamber: transport delay + its volume | spool delay, dead volume | yes (delay) |
| pressure_sensor_offset, angle_sensor_offset | additive sensor offsets | observations | yes (pressure and torque balance) |
| supply_droop | supply pressure falls with the total supply flow | kernel | yes |
| end_stop | a bumper inside the joint range: one-sided spring past the stop | MuJoCo soft joint limit | yes (stiffness >= 20 N m/rad; not concealable, so outside the blind benchmark) |
| external_leak (bench) | laminar leak through the pores of a printed chamber (`external_leak.py`) | bench_chamber | bench doctor |
| heat_transfer | gas temperature as a state, energy equation with h A (T_wall - T) (`heat_transfer.py`, R&H 2000 eq. 11) | per chamber, stepped in Python (~1 ms/step) | yes (T observed from the measured pressures, `identification/thermal.py`); bench doctor |
| force_sensor_offset | load-cell offset; seal friction per direction and its growth with pressure (`seal_friction.py`) | bench_cylinder | bench doctor |
| backlash | play between cylinder and link, dead zone (`backlash.py`, Nordin & Gutman 2002) | drive hinge + limited fixed tendon in MuJoCo | yes (the piston leads the link by gap/2 on the side it pushes) |
"""

from .registry import FAMILIES, get_family

#: every family name the doctor can report (DESIGN.md; extend, never rename): the registry's
VOCABULARY = tuple(FAMILIES)
