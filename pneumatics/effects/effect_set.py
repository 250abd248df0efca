"""Effects switched on in a :class:`pneumatics.sim.Simulation` (or found by the doctor).

Places are named like recording columns: a joint (``"elbow"``), an actuator (``"elbow"``) or
a chamber (``"elbow.b"``).  Every value carries its unit in its name.  Each field belongs to
one family of :mod:`pneumatics.effects.registry`, whose module holds the law, its sources and
the entry it makes here (``Family.effect_set_entry``); :meth:`EffectSet.add` switches a family
on by name, its parameters checked against their units.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, UnknownNameError
from .end_stop import END_STOP_TIMECONST_S
from .supply_droop import COMPRESSOR_FIELDS
from .valve_leak import CLEARANCE_WIDTH_V, UNDERLAP_WIDTH_V, WIDTH_V

#: the supply's fields: one supply, so one form of supply_droop at a time
SUPPLY_FIELDS = ("supply_droop_pa_per_kg_s", "supply_droop_pa_per_kg2_s2", "supply_droop_tau_s", *COMPRESSOR_FIELDS)


@dataclass
class EffectSet:
    friction: dict = field(default_factory=dict)
    """joint -> {"coulomb_nm", "stiction_extra_nm", "stribeck_rad_s", "viscous_nm_s", "power_viscous_nm",
    "viscous_exponent"} (coulomb_friction, stiction, viscous_friction); written into ``data.qfrc_applied`` of those joints every step,
    replacing what a user put there."""
    valve_leak_m2: dict = field(default_factory=dict)
    """chamber -> extra area open both ways near null [m^2] (valve_leak; Gaussian of width valve_leak_width_v)"""
    valve_leak_exhaust_m2: dict = field(default_factory=dict)
    """chamber -> the leak's exhaust-side area [m^2] where it differs from the supply side's
    (``valve_leak_m2``): the two lands of a spool need not be underlapped alike, which moves the
    pressure the leak pulls the chamber towards"""
    valve_underlap: dict = field(default_factory=dict)
    """chamber -> {"area_m2": area each land is open at null [m^2], "width_v": the underlap [V]}
    (valve_leak, underlap form: effects.valve_leak.underlap_areas)"""
    valve_clearance: dict = field(default_factory=dict)
    """chamber -> {"conductance_kg_s_pa": laminar conductance of each land at null [kg/(s Pa)],
    "width_v": the overlap [V]} (valve_leak, clearance form: effects.valve_leak.clearance_conductances)"""
    valve_leak_width_v: float = WIDTH_V
    """command distance from null over which the valve_leak closes [V] (effects.valve_leak)"""
    external_leak_m2: dict = field(default_factory=dict)
    """chamber -> effective area of a leak to the room [m^2] (external_leak)"""
    piston_leak_m2: dict = field(default_factory=dict)
    """actuator -> effective area of a leak across the piston [m^2] (piston_leak)"""
    external_leak_laminar_kg_s_pa: dict = field(default_factory=dict)
    """chamber -> conductance G [kg/(s Pa)] of a laminar (capillary) leak to the room, the
    external_leak's second form: m = G (p^2 - p_room^2) / (2 p_room) (effects.external_leak)"""
    piston_leak_laminar_kg_s_pa: dict = field(default_factory=dict)
    """actuator -> conductance G [kg/(s Pa)] of a laminar leak past the piston seal, a -> b:
    m = G (p_a^2 - p_b^2) / (2 p_room) (piston_leak's second form)"""
    valve_hysteresis_v: dict = field(default_factory=dict)
    """chamber -> half-width of the play between command and spool [V] (valve_hysteresis)"""
    pressure_offset_pa: dict = field(default_factory=dict)
    """chamber -> sensor reads true + offset [Pa] (pressure_sensor_offset)"""
    pressure_drift: dict = field(default_factory=dict)
    """chamber -> {"drift_pa": the offset's change while the sensor warms up [Pa],
    "time_constant_s": its time constant [s]}: the reading's offset is offset + drift
    (1 - exp(-t / tau)), t the simulation's time (pressure_sensor_offset, warm_up_drift form)"""
    angle_offset_rad: dict = field(default_factory=dict)
    """joint -> sensor reads true + offset [rad] (angle_sensor_offset)"""
    angle_scale_error: dict = field(default_factory=dict)
    """joint -> the sensor's gain error: it reads (1 + scale_error) q + offset, its rate
    (1 + scale_error) qd [-] (angle_sensor_offset, offset_and_scale form)"""
    supply_droop_pa_per_kg_s: float = 0.0
    """supply pressure drop per kg/s of the total flow the valves draw (supply_droop)"""
    supply_droop_pa_per_kg2_s2: float = 0.0
    """supply pressure drop per (kg/s)^2 of that flow (supply_droop, regulator_orifice form)"""
    supply_droop_tau_s: float = 0.0
    """time constant [s] of the receiver behind the regulator: the droop follows the total flow
    low-passed with it (supply_droop, reservoir and regulator_orifice forms; 0 = no receiver)"""
    supply_receiver_m3: float = 0.0
    """volume of the receiver a switched compressor refills (supply_droop, compressor_cycling
    form; 0 = none): the supply pressure is the receiver's"""
    supply_compressor_kg_s: float = 0.0
    """the compressor's delivery while it runs [kg/s] (compressor_cycling)"""
    supply_band_pa: float = 0.0
    """cut-out minus cut-in pressure of its switch [Pa] (compressor_cycling)"""
    supply_cut_out_pa: float = 0.0
    """the pressure its switch stops it at [Pa abs] (compressor_cycling)"""
    supply_leak_kg_s_pa: float = 0.0
    """the system's leak conductance to the room [kg/(s Pa)] (compressor_cycling)"""
    valve_lag_s: dict = field(default_factory=dict)
    """chamber -> time constant of the spool's first-order lag behind its command [s] (valve_lag)"""
    valve_slew_s: dict = field(default_factory=dict)
    """chamber -> least time the spool takes to cross the whole command range [s] (valve_lag,
    slew_limit form): its speed is bounded by COMMAND_SPAN_V / that time"""
    line_dynamics: dict = field(default_factory=dict)
    """chamber -> {"delay_s": transport delay of the tube between valve and chamber [s],
    "volume_m3": the tube's volume, added to the chamber's dead volume [m^3]} (line_dynamics), or
    (its lumped_rc form) {"tube_volume_m3": the tube's volume at its own pressure [m^3],
    "tube_time_constant_s": its resistance's time constant [s]}: the tube's pressure is a state
    (effects/line_dynamics.rc_line_step) and such a simulation steps in Python"""
    heat_transfer: dict = field(default_factory=dict)
    """chamber -> {"conductance_w_k": h A_w between gas and wall [W/K]} (heat_transfer): the chamber
    carries its gas temperature and follows the energy equation (effects/heat_transfer.thermal_step,
    Richer & Hurmuzlu 2000 eq. 11) instead of paper 002 eq. 9; the wall is at the gas table's
    temperature_k.  Such a simulation steps in Python (about 10x slower)."""
    end_stop: dict = field(default_factory=dict)
    """joint -> {"upper_intrusion_rad" or "lower_intrusion_rad": how far inside the model's joint
    limit a rubber bumper stops the joint [rad]} (end_stop); MuJoCo's own soft joint limit, with
    the bumper's time constant END_STOP_TIMECONST_S"""
    backlash: dict = field(default_factory=dict)
    """joint -> {"gap_rad": total play between cylinder and link [rad]} (backlash); the cylinder
    drives a hinge of its own, coupled to the link through MuJoCo's tendon limit
    (:func:`pneumatics.effects.backlash.backlash_model`)"""

    def add(self, family: str, place: str, values: dict, form: str | None = None) -> "EffectSet":
        """Switch ``family`` on at ``place`` (``"all"`` for the supply) with parameters ``values``
        (the fields of the family's ``form``, default its first; units and ranges checked).
        Returns self, so calls chain."""
        from .registry import get_family

        fam = get_family(family)
        fam.add_to(self, place, fam.params(values, form))
        return self

    def combined(self, other: "EffectSet") -> "EffectSet":
        """A new EffectSet with the effects of both (a fitted model's and a study's, e.g. tubes
        added to a fitted humanoid).  One family at one place in both, or two supply droops,
        is a ConfigError naming it: which of the two should win is the caller's choice."""
        out = EffectSet(valve_leak_width_v=self.valve_leak_width_v)
        for f in dataclasses.fields(EffectSet):
            mine, theirs = getattr(self, f.name), getattr(other, f.name)
            if isinstance(mine, dict):
                both = sorted(set(mine) & set(theirs))
                if both:
                    raise ConfigError(f"combining effect sets: {f.name} is set at {', '.join(both)} in both")
                getattr(out, f.name).update({**mine, **theirs})
        if self.has_supply_effect and other.has_supply_effect:
            raise ConfigError("combining effect sets: a supply droop in both")
        mine = self if self.has_supply_effect else other
        for name in SUPPLY_FIELDS:
            setattr(out, name, getattr(mine, name))
        return out

    def _array(self, attr: str, kind: str, names: list) -> np.ndarray:
        """(len(names),) values of the per-place effect ``attr``; 0 where it is off."""
        out = np.zeros(len(names))
        for key, v in getattr(self, attr).items():
            if key not in names:
                raise UnknownNameError(kind, key, names)
            out[names.index(key)] = v
        return out

    def chamber_array(self, robot, attr: str) -> np.ndarray:
        return self._array(attr, "chamber", [f"{a}.{c}" for a, c in robot.chamber_names])

    def actuator_array(self, robot, attr: str) -> np.ndarray:
        return self._array(attr, "actuator", robot.actuator_names)

    def joint_array(self, robot, attr: str) -> np.ndarray:
        return self._array(attr, "joint", robot.joint_names)

    def _chamber_fields(self, robot, attr: str, defaults: dict) -> tuple[np.ndarray, ...]:
        """One (n_ch,) array per key of ``defaults`` from the per-chamber dicts of ``attr``:
        each chamber's value, the default where the chamber or the key is absent."""
        names = [f"{a}.{c}" for a, c in robot.chamber_names]
        out = {k: np.full(len(names), d, float) for k, d in defaults.items()}
        for key, v in getattr(self, attr).items():
            if key not in names:
                raise UnknownNameError("chamber", key, names)
            for k, d in defaults.items():
                out[k][names.index(key)] = v.get(k, d)
        return tuple(out.values())

    def line_arrays(self, robot) -> tuple[np.ndarray, np.ndarray]:
        """(delay_s, volume_m3), each (n_ch,), of the line_dynamics effects."""
        return self._chamber_fields(robot, "line_dynamics", {"delay_s": 0.0, "volume_m3": 0.0})

    def tube_arrays(self, robot) -> tuple[np.ndarray, np.ndarray]:
        """(tube_volume_m3, time_constant_s), each (n_ch,), of the lumped_rc lines (volume 0 elsewhere)."""
        return self._chamber_fields(robot, "line_dynamics", {"tube_volume_m3": 0.0, "tube_time_constant_s": 0.01})

    def underlap_arrays(self, robot) -> tuple[np.ndarray, np.ndarray]:
        """(area_m2, width_v), each (n_ch,), of the underlapped valves (area 0 elsewhere)."""
        return self._chamber_fields(robot, "valve_underlap", {"area_m2": 0.0, "width_v": UNDERLAP_WIDTH_V})

    def clearance_arrays(self, robot) -> tuple[np.ndarray, np.ndarray]:
        """(conductance_kg_s_pa, width_v), each (n_ch,), of the valves whose lands seal by a
        clearance (conductance 0 elsewhere)."""
        return self._chamber_fields(robot, "valve_clearance", {"conductance_kg_s_pa": 0.0, "width_v": CLEARANCE_WIDTH_V})

    def drift_arrays(self, robot) -> tuple[np.ndarray, np.ndarray]:
        """(drift_pa, time_constant_s), each (n_ch,), of the warming-up pressure sensors
        (time constant 0, no drift, elsewhere)."""
        return self._chamber_fields(robot, "pressure_drift", {"drift_pa": 0.0, "time_constant_s": 0.0})

    def heat_arrays(self, robot) -> tuple[np.ndarray, np.ndarray]:
        """(thermal mask (n_ch,) bool, conductance [W/K] (n_ch,)) of the heat_transfer effects."""
        names = [f"{a}.{c}" for a, c in robot.chamber_names]
        mask, hA = np.zeros(len(names), bool), np.zeros(len(names))
        for key, v in self.heat_transfer.items():
            if key not in names:
                raise UnknownNameError("chamber", key, names)
            mask[names.index(key)] = True
            hA[names.index(key)] = v.get("conductance_w_k", 0.0)
        return mask, hA

    def apply_end_stops(self, robot, model):
        """Narrow the joint limits of ``model`` (a copy of the robot's) to the end stops."""
        for joint, v in self.end_stop.items():
            if joint not in robot.joint_names:
                raise UnknownNameError("joint", joint, robot.joint_names)
            jid = model.joint(joint).id
            lo, hi = model.jnt_range[jid]
            if not model.jnt_limited[jid]:
                lo, hi = -np.pi, np.pi
            model.jnt_limited[jid] = 1
            model.jnt_range[jid] = (lo + v.get("lower_intrusion_rad", 0.0), hi - v.get("upper_intrusion_rad", 0.0))
            model.jnt_solref[jid] = (END_STOP_TIMECONST_S, 1.0)

    def friction_table(self, robot, model=None) -> np.ndarray:
        """(n_f, 7): dof address (in ``model``, default the robot's), Coulomb, extra breakaway,
        Stribeck velocity, viscous, the velocity-power term's coefficient and exponent
        (pneumatics.effects.friction.friction_torque's arguments in order)."""
        model = robot.model if model is None else model
        rows = []
        for joint, f in self.friction.items():
            if joint not in robot.joint_names:
                raise UnknownNameError("joint", joint, robot.joint_names)
            dof = model.jnt_dofadr[model.joint(joint).id]
            rows.append([dof, f.get("coulomb_nm", 0.0), f.get("stiction_extra_nm", 0.0),
                         f.get("stribeck_rad_s", 0.1), f.get("viscous_nm_s", 0.0), f.get("power_viscous_nm", 0.0),
                         f.get("viscous_exponent", 1.0)])
        return np.array(rows, float).reshape(-1, 7)

    @property
    def has_supply_effect(self) -> bool:
        return bool(self.supply_droop_pa_per_kg_s or self.supply_droop_pa_per_kg2_s2 or self.supply_receiver_m3)

    def compressor_array(self) -> np.ndarray | None:
        """(5,) the compressor_cycling form's values in COMPRESSOR_FIELDS order, None when off."""
        return np.array([getattr(self, n) for n in COMPRESSOR_FIELDS], float) if self.supply_receiver_m3 > 0 else None

    @property
    def empty(self) -> bool:
        return not any((self.friction, self.valve_leak_m2, self.valve_leak_exhaust_m2, self.valve_underlap, self.valve_clearance,
                        self.external_leak_m2, self.piston_leak_m2,
                        self.external_leak_laminar_kg_s_pa, self.piston_leak_laminar_kg_s_pa,
                        self.valve_hysteresis_v, self.pressure_offset_pa, self.pressure_drift, self.angle_offset_rad,
                        self.angle_scale_error,
                        self.supply_droop_pa_per_kg_s, self.supply_droop_pa_per_kg2_s2, self.supply_receiver_m3, self.valve_lag_s, self.valve_slew_s, self.line_dynamics, self.end_stop,
                        self.heat_transfer, self.backlash))
