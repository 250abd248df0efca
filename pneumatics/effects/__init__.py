"""Physical effects a nominal model may leave out (DESIGN.md effect vocabulary).

Each module is a small physical model with named, unit-carrying parameters.  The same
functions serve the mismatch finder (``identification/hypotheses.py``) as hypotheses, so
whatever it finds can be simulated and plotted.

| family | module | physics |
| --- | --- | --- |
| coulomb_friction, stiction, viscous_friction | friction | Coulomb + Stribeck + viscous torque (Armstrong-Helouvry 1994) |
| valve_leak, piston_leak, external_leak | leaks | orifice flows: spool not shut at null, across the piston, to the room |
| valve_hysteresis, valve_lag | valve_dynamics | play operator on the command; first-order lag and dead time |
| line_dynamics | valve_dynamics | tube between valve and port: transport delay + extra volume |
| pressure_sensor_offset, angle_sensor_offset | sensors | additive offsets |
| supply_droop | supply | supply pressure falls with the total supply flow |
| heat_transfer | heat | finite heat exchange between gas and wall (Newton cooling) |
| end_stop | friction | stiff spring beyond a joint position |
"""

#: every family name the doctor can report (DESIGN.md; extend, never rename)
VOCABULARY = (
    "coulomb_friction", "stiction", "viscous_friction", "valve_leak", "piston_leak",
    "valve_hysteresis", "valve_lag", "line_dynamics", "heat_transfer", "pressure_sensor_offset",
    "angle_sensor_offset", "supply_droop", "end_stop", "backlash", "external_leak",
    "force_sensor_offset",
)
