"""What changes the nominal chamber model: the calibration's scales and the pneumatic effects'
parameters, per chamber, as the pressure replays (:mod:`pneumatic`), the compiled step
(:mod:`chamber_kernel`) and the coupled replays read them; and the leak flows those
parameters imply (the effects' own laws, pneumatics/effects)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from pneumatics.effects.external_leak import laminar_flow
from pneumatics.effects.pressure_sensor_offset import offset_at
from pneumatics.effects.valve_leak import (CLEARANCE_WIDTH_V, UNDERLAP_WIDTH_V, WIDTH_V, clearance_conductances,
                                          clearance_flows, leak_areas, underlap_areas)
from pneumatics.medium import orifice_flow


@dataclass
class PneumaticMods:
    """Changes to the nominal chamber model; arrays are per chamber (C,) unless noted.

    The effect fields are filled by the families' own hooks (pneumatics/effects/<family>.py,
    ``Family.apply_to_mods``); the compiled step (chamber_kernel) reads the same arrays."""

    supply_scale: np.ndarray          # multiplies each valve's supply areas
    exhaust_scale: np.ndarray         # multiplies each valve's exhaust areas
    dead_volume_scale: np.ndarray     # multiplies each chamber's dead volume
    valve_leak_m2: np.ndarray = None          # extra area open both ways near null (valve_leak)
    valve_leak_exhaust_m2: np.ndarray = None  # its exhaust-side area where it differs (None: the same)
    valve_leak_width_v: float = WIDTH_V
    valve_underlap_m2: np.ndarray = None      # an underlapped spool's area at null (valve_leak, underlap form)
    valve_underlap_width_v: np.ndarray = None # its underlap [V] (None: UNDERLAP_WIDTH_V)
    valve_clearance_g: np.ndarray = None      # an overlapped spool's land conductance at null [kg/(s Pa)]
                                              # (valve_leak, clearance form)
    valve_clearance_width_v: np.ndarray = None  # its overlap [V] (None: CLEARANCE_WIDTH_V)
    external_leak_m2: np.ndarray = None       # orifice from the chamber to the room
    piston_leak_m2: np.ndarray = None         # (n_act,) orifice between chambers a and b
    external_leak_g: np.ndarray = None        # laminar leak to the room, conductance [kg/(s Pa)]
    piston_leak_g: np.ndarray = None          # (n_act,) laminar leak between a and b [kg/(s Pa)]
    hysteresis_v: np.ndarray = None           # play half-width on each valve's command
    lag_s: np.ndarray = None                  # first-order valve lag
    stroke_time_s: np.ndarray = None          # the spool's least full-stroke time (valve_lag, slew_limit)
    delay_s: np.ndarray = None                # command dead time
    extra_volume_m3: np.ndarray = None        # line volume added to the dead volume
    tube_volume_m3: np.ndarray = None         # a lumped line's tube at its own pressure [m^3] (line_dynamics, lumped_rc)
    tube_time_constant_s: np.ndarray = None   # ... its resistance's time constant [s]
    sensor_offset_pa: np.ndarray = None       # measured = true + offset
    sensor_drift_pa: np.ndarray = None        # + drift (1 - exp(-t / tau)), a sensor warming up
    sensor_drift_tau_s: np.ndarray = None     # its time constant tau [s] (0: no drift)
    supply_droop_pa_per_kg_s: float = 0.0     # supply pressure drop per kg/s of total supply flow
    supply_droop_pa_per_kg2_s2: float = 0.0   # ... per (kg/s)^2 of it (regulator_orifice)
    supply_droop_tau_s: float = 0.0           # ... that flow low-passed with this time constant [s] (reservoir)
    supply_receiver_m3: float = 0.0           # compressor_cycling: the receiver's volume (0: none) ...
    supply_compressor_kg_s: float = 0.0       # ... the compressor's delivery [kg/s]
    supply_band_pa: float = 0.0               # ... its switch's cut-out minus cut-in [Pa]
    supply_cut_out_pa: float = 0.0            # ... its cut-out [Pa abs]
    supply_leak_kg_s_pa: float = 0.0          # ... the system's leak to the room [kg/(s Pa)]
    receiver_paths: dict = None               # recording set key (receiver.experiment_key) -> (F,) the receiver's
                                              # pressure [Pa] along it, as its fit left it (supply_receiver)
    supply_paths: dict = None                 # recording set key -> (F,) the supply pressure [Pa] held along it in
                                              # place of the supply's laws (supply_path.with_held_supply)
    heat_w_k: np.ndarray = None               # gas-wall conductance h A [W/K]; NaN = eq. 9 (heat_transfer)
    backlash_rad: np.ndarray = None           # (n_act,) play between cylinder and link [rad] (backlash)
    wall_compliance_m3_pa: np.ndarray = None  # dV/dp of a compliant wall [m^3/Pa]: V += C (p - p_room); not a
                                              # family (the check of a line's constant volume, compliance.py)

    @classmethod
    def nominal(cls, n_ch: int) -> "PneumaticMods":
        return cls(np.ones(n_ch), np.ones(n_ch), np.ones(n_ch))

    def valve_leak_exhaust(self):
        """The valve_leak's exhaust-side extra area per chamber (C,) or None: its own where the
        asymmetric hypothesis set one, else the supply side's (the symmetric leak)."""
        return self.valve_leak_m2 if self.valve_leak_exhaust_m2 is None else self.valve_leak_exhaust_m2

    def valve_leak_areas(self, u, null_v, cs=slice(None)):
        """(supply, exhaust) extra areas [m^2] of the valve_leak at commands ``u`` [V] of the
        chambers ``cs`` whose valves' null is ``null_v``: Gaussian in u - null, plus the
        underlapped spool's shifted areas (underlap_areas); (0, 0) if none."""
        out_s = out_e = 0.0
        if self.valve_leak_m2 is not None or self.valve_leak_exhaust_m2 is not None:
            supply = 0.0 if self.valve_leak_m2 is None else self.valve_leak_m2[cs]
            out_s, out_e = leak_areas(u, null_v, supply, self.valve_leak_exhaust()[cs], self.valve_leak_width_v)
        if self.valve_underlap_m2 is not None:
            width = UNDERLAP_WIDTH_V if self.valve_underlap_width_v is None else self.valve_underlap_width_v[cs]
            lap_s, lap_e = underlap_areas(u, null_v, self.valve_underlap_m2[cs], width)
            out_s, out_e = out_s + lap_s, out_e + lap_e
        return out_s, out_e

    def valve_clearance_flow(self, u, null_v, p, supply_pa, room_pa: float, cs=slice(None)):
        """(m, dm/dp) [kg/s, kg/(s Pa)] into the chambers ``cs`` at pressures ``p`` through their
        valves' land clearances at commands ``u`` [V] (null ``null_v``), from the supply at
        ``supply_pa`` and to the room (effects.valve_leak.clearance_flows); (0, 0) if none."""
        if self.valve_clearance_g is None:
            return 0.0, 0.0
        return clearance_flows(*self.valve_clearance_conductances(u, null_v, cs), p, supply_pa, room_pa)

    def valve_clearance_conductances(self, u, null_v, cs=slice(None)):
        """(supply land, exhaust land) conductances [kg/(s Pa)] of the chambers ``cs``' valves at
        commands ``u`` [V] (null ``null_v``): effects.valve_leak.clearance_conductances; (0, 0)
        if none."""
        if self.valve_clearance_g is None:
            return 0.0, 0.0
        width = CLEARANCE_WIDTH_V if self.valve_clearance_width_v is None else self.valve_clearance_width_v[cs]
        return clearance_conductances(u, null_v, self.valve_clearance_g[cs], width)

    def chamber_leak_flow(self, q, room_pa: float, gas):
        """(W, C) the flow [kg/s] into each chamber at pressures ``q`` (W, C) through the external
        and piston leaks (orifice and laminar forms), equal and opposite across a piston: what
        the thermal and the lumped line's steps hold over a step."""
        out = -self.external_leak_flow(q, room_pa, gas)[0] * np.ones_like(q)
        if self.piston_leak_m2 is not None or self.piston_leak_g is not None:
            m_ab = self.piston_leak_flow(q, room_pa, gas)[0]
            out[:, 0::2] -= m_ab
            out[:, 1::2] += m_ab
        return out

    def external_leak_flow(self, p, room_pa: float, gas, cs=slice(None)):
        """(m, dm/dp) [kg/s, kg/(s Pa)] out of the chambers ``cs`` at pressures ``p`` through the
        external leak, its orifice and laminar forms together (0, 0 if none)."""
        m = dm = 0.0
        if self.external_leak_m2 is not None:
            m_x, dmx, _ = orifice_flow(self.external_leak_m2[cs], p, room_pa, gas)
            m, dm = m + m_x, dm + dmx
        if self.external_leak_g is not None:
            m_x, dmx, _ = laminar_flow(self.external_leak_g[cs], p, room_pa, room_pa)
            m, dm = m + m_x, dm + dmx
        return m, dm

    def piston_leak_flow(self, q, room_pa: float, gas):
        """(m_ab, d/dp_a, d/dp_b), each (W, n_act), from pressures q (W, C): the piston leak
        a -> b, its orifice and laminar forms together."""
        out = [np.zeros(q[:, 0::2].shape)] * 3
        if self.piston_leak_m2 is not None:
            out = [o + x for o, x in zip(out, orifice_flow(self.piston_leak_m2, q[:, 0::2], q[:, 1::2], gas))]
        if self.piston_leak_g is not None:
            out = [o + x for o, x in zip(out, laminar_flow(self.piston_leak_g, q[:, 0::2], q[:, 1::2], room_pa))]
        return out

    def sensor_offsets(self, clock):
        """What the pressure sensors add to the true pressures [Pa] at recording times
        ``clock`` (any shape; the result that shape + (C,), or (C,) without drift), or None
        without offsets (effects.pressure_sensor_offset.offset_at)."""
        if self.sensor_offset_pa is None and self.sensor_drift_pa is None:
            return None
        offset = 0.0 if self.sensor_offset_pa is None else self.sensor_offset_pa
        if self.sensor_drift_pa is None or not np.any(self.sensor_drift_pa):
            return np.broadcast_to(offset, (self.supply_scale.size,)).astype(float)
        return offset_at(np.asarray(clock, float)[..., None], offset, self.sensor_drift_pa, self.sensor_drift_tau_s)

    def copy(self, **changes) -> "PneumaticMods":
        out = dataclasses.replace(self)
        for k, v in vars(out).items():
            if isinstance(v, np.ndarray):
                setattr(out, k, v.copy())
        for k, v in changes.items():
            setattr(out, k, v)
        return out
