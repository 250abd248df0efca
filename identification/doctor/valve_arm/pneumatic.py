"""Short pressure replays of every chamber, driven by the *measured* motion and commands.

Each window starts from the measured pressures and integrates paper 002 eq. 9 over 1 ms steps
with the chamber volumes that the recorded joint angles imply, so the chambers' own physics
is tested without the rigid body in the loop (an output-error test with restarts, immune to
the drift of a free-running arm).  All windows and chambers integrate together as one batch.

The chamber model can be modified by :class:`PneumaticMods` — calibration scales and the
pneumatic effect hypotheses — and outputs what the DAQ would have recorded (10 ms means).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from pneumatics.chamber import GAMMA
from pneumatics.effects.heat_transfer import thermal_step
from pneumatics.effects.valve_dynamics import dead_time, first_order_lag, play, slew_limited
from pneumatics.effects.valve_lag import slew_step_v
from pneumatics.effects.valve_leak import CLEARANCE_WIDTH_V, UNDERLAP_WIDTH_V
from pneumatics.effects.supply_droop import droop_pa, filtered_flow
from pneumatics.kernel import pack_glob
from pneumatics.medium import orifice_flow
from pneumatics.valve import valve_areas

from .chamber_kernel import replay_batch, step_batch
from .data import FINE_DT, Experiment, fine_pressures
from .pneumatic_mods import PneumaticMods
from .receiver import compressor_of, held_path, measured_supply_flow, receiver_trajectory
from .thermal import gas_temperatures
from .tubes import has_tubes, start_tubes, tube_step_reference


#: the place of the windows' low-passed supply flow (W,) [kg/s] among the compiled step's
#: arguments (ChamberModel._pack_kernel), a state the kernel updates
SUPPLY_FLOW_ARG = 16


@dataclass
class Windows:
    """Replay windows: start sample indices (W,) and horizon in samples."""

    starts: np.ndarray
    horizon: int

    @classmethod
    def tile(cls, n_samples: int, horizon: int, stride: int | None = None, first: int = 2,
             breaks: tuple = (), settle: int = 10) -> "Windows":
        """Windows every ``stride`` samples; with ``breaks`` (joins of pooled recordings) none
        straddles a join, and each segment's first ``settle`` samples are skipped (valve
        memory — lag, hysteresis — carried over the join)."""
        stride = stride or horizon
        edges = [0, *breaks, n_samples]
        starts = [np.arange(a + (first if i == 0 else settle), b - horizon - 1, stride)
                  for i, (a, b) in enumerate(zip(edges[:-1], edges[1:]))]
        return cls(np.concatenate(starts).astype(int), horizon)


def effective_commands(exp: Experiment, mods: PneumaticMods) -> np.ndarray:
    """(F, C) commands on the 1 ms grid after hysteresis, lag, slew limit and dead time."""
    u = exp.u.copy()
    if mods.hysteresis_v is not None:
        for c in np.nonzero(mods.hysteresis_v > 0)[0]:
            u[:, c] = play(u[:, c], mods.hysteresis_v[c])
    n_f = exp.fine_t.size
    idx = np.minimum(np.arange(n_f) // exp.n_sub, exp.u.shape[0] - 1)
    fine = u[idx]
    if mods.lag_s is not None:
        for c in np.nonzero(mods.lag_s > 0)[0]:
            fine[:, c] = first_order_lag(fine[:, c], mods.lag_s[c], FINE_DT)
    if mods.stroke_time_s is not None:
        for c in np.nonzero(mods.stroke_time_s > 0)[0]:
            fine[:, c] = slew_limited(fine[:, c], float(slew_step_v(mods.stroke_time_s[c], FINE_DT)))
    if mods.delay_s is not None:
        for c in np.nonzero(mods.delay_s > 0)[0]:
            fine[:, c] = dead_time(fine[:, c], mods.delay_s[c], FINE_DT)
    return fine


class ChamberModel:
    """The (modified) chamber equations for a batch (W, C) of chamber sets; one 1 ms step at a
    time.  Shared by the pressure replays and the coupled replays (:mod:`replay`)."""

    def __init__(self, robot, mods: PneumaticMods, batch: int, chambers: np.ndarray | None = None):
        """``chambers``: whole cylinders' chambers (indices, a and b of each in turn) that
        :meth:`step` alone computes, its arrays (W, len(chambers)); only where they replay
        independently of the others (:func:`chambers_independent`).  None: every chamber."""
        tab = robot.tables
        self.tab, self.mods, self.W = tab, mods, batch
        self.chambers = chambers
        self.gas = tab.gas
        self.rt = self.gas.gas_constant_j_per_kg_k * self.gas.temperature_k
        self.n = self.gas.polytropic_exponent
        self.dead = tab.dead_volume * mods.dead_volume_scale
        if mods.extra_volume_m3 is not None:
            self.dead = self.dead + mods.extra_volume_m3
        self.m_supply_total = np.zeros((batch, 1))
        # heat_transfer: these chambers carry a gas temperature T (W, C) [K]; set T before stepping
        self.thermal = np.array([], int) if mods.heat_w_k is None else np.nonzero(np.isfinite(mods.heat_w_k))[0]
        if mods.tube_volume_m3 is not None:  # a lumped line's chamber takes the tube's step instead (chamber_kernel)
            self.thermal = self.thermal[~(np.asarray(mods.tube_volume_m3)[self.thermal] > 0)]
        n_step = tab.n_chambers if chambers is None else len(chambers)
        self.T = np.full((batch, n_step), self.gas.temperature_k)
        # line_dynamics (lumped_rc): the tubes' pressures (W, C) [Pa], NaN until a step starts them settled
        self.p_tube = np.full((batch, n_step), np.nan)
        self.supply_shift = np.zeros(batch)  # (W,) the supply pressure's departure from the table's [Pa] (a receiver)
        self._kernel_args = self._pack_kernel()

    def _pack_kernel(self):
        """Arguments of the compiled step (identification.doctor.valve_arm.chamber_kernel) for
        these mods, each chamber's and cylinder's taken for the chambers it steps (the kernel
        pairs chambers 2j, 2j + 1 as cylinder j: whole cylinders keep the pairing)."""
        tab, mods = self.tab, self.mods
        C = tab.n_chambers
        own = slice(None) if self.chambers is None else self.chambers
        own_cylinders = slice(None) if self.chambers is None else self.chambers[0::2] // 2

        def per(arr, fill=0.0):
            # writable copies: numba compiles read-only arrays (a broadcast view) as another type
            full = np.full(C, fill) if arr is None else np.array(np.broadcast_to(arr, (C,)), float)
            return np.ascontiguousarray(full[own])

        def per_cylinder(arr):
            full = np.zeros(C // 2) if arr is None else np.array(np.broadcast_to(arr, (C // 2,)), float)
            return np.ascontiguousarray(full[own_cylinders])

        glob = pack_glob(self.gas, tab.supply_pa, tab.room_pa, FINE_DT, float(mods.supply_droop_pa_per_kg_s),
                         float(mods.supply_droop_tau_s), droop_pa_per_kg2_s2=float(mods.supply_droop_pa_per_kg2_s2))
        return (np.ascontiguousarray(np.array(tab.valve, float)[own]), per(mods.supply_scale), per(mods.exhaust_scale),
                per(mods.valve_leak_m2), per(mods.valve_leak_exhaust()), float(mods.valve_leak_width_v),
                per(mods.valve_underlap_m2), per(mods.valve_underlap_width_v, UNDERLAP_WIDTH_V),
                per(mods.valve_clearance_g), per(mods.valve_clearance_width_v, CLEARANCE_WIDTH_V),
                per(mods.external_leak_m2), per_cylinder(mods.piston_leak_m2),
                per(mods.external_leak_g), per_cylinder(mods.piston_leak_g), per(self.dead), per(tab.area),
                np.zeros(self.W), glob, per(mods.heat_w_k, np.nan), per(mods.wall_compliance_m3_pa),
                per(mods.tube_volume_m3), per(mods.tube_time_constant_s, 0.01))

    def travel(self, length, chambers=slice(None)):
        """Chamber travel (W, C) from actuator lengths (W, n_act); only the columns ``chambers``
        (indices) if given (a replay of a few of a humanoid's 76 chambers)."""
        tab = self.tab
        act = tab.actuator_of_chamber[chambers]
        x = np.clip(length[:, act] - tab.length_zero[act], 0.0, tab.stroke[act])
        return np.where(tab.is_a[chambers], x, tab.stroke[act] - x)

    def step(self, p, u, travel0, travel1):
        """p (W, C) -> p after one FINE_DT step with commands u (W, C) and travels at its ends.

        Compiled (identification.doctor.valve_arm.chamber_kernel); :meth:`step_reference` is its numpy twin.
        Chambers with heat_transfer update their gas temperatures ``self.T`` (W, C) [K]."""
        rows, ss, es, vl, vle, vw, ul, uw, cg, cw, xl, pl, xg, pg, dead, area, m_sup, glob, heat, wall, tv, tt = \
            self._kernel_args
        out = np.empty_like(p)
        W = p.shape[0]
        T = np.ascontiguousarray(self.T[:W], float)
        p_tube = np.ascontiguousarray(self.p_tube[:W], float)
        step_batch(np.ascontiguousarray(p, float), np.ascontiguousarray(u, float), np.ascontiguousarray(travel0, float),
                   np.ascontiguousarray(travel1, float), rows, ss, es, vl, vle, vw, ul, uw, cg, cw, xl, pl, xg, pg, dead, area,
                   m_sup[:W], glob, out, heat, T, wall, self.supply_shift[:W], tv, tt, p_tube)
        self.T[:W] = T
        self.p_tube[:W] = p_tube
        return out

    def run_windows(self, p, u_fine, travel, first, horizon: int, n_sub: int, averaged: bool, receiver):
        """(W, horizon, C) the pressures [Pa] of windows starting at fine steps ``first`` (W,)
        from ``p`` (W, C), ``n_sub`` fine steps a sample (each sample the mean of its steps when
        ``averaged``), commands ``u_fine`` and travels ``travel`` (F, C) on the fine grid, the
        supply following ``receiver`` (F,) [Pa] if not None.  Compiled
        (chamber_kernel.replay_batch); :meth:`run_windows_reference` is its Python twin."""
        rows, ss, es, vl, vle, vw, ul, uw, cg, cw, xl, pl, xg, pg, dead, area, m_sup, glob, heat, wall, tv, tt = \
            self._kernel_args
        W, C = p.shape
        out = np.zeros((W, horizon, C))
        T = np.ascontiguousarray(self.T[:W], float)
        p_tube = np.ascontiguousarray(self.p_tube[:W], float)
        path = np.zeros(0) if receiver is None else np.ascontiguousarray(receiver, float)
        replay_batch(np.array(p, float), np.ascontiguousarray(u_fine, float), np.ascontiguousarray(travel, float),
                     np.ascontiguousarray(first, np.int64), int(horizon), int(n_sub), bool(averaged), path,
                     float(self.tab.supply_pa), rows, ss, es, vl, vle, vw, ul, uw, cg, cw, xl, pl, xg, pg, dead, area,
                     m_sup[:W], glob, heat, T, wall, self.supply_shift[:W], tv, tt, p_tube, out)
        self.T[:W] = T
        self.p_tube[:W] = p_tube
        return out

    def run_windows_reference(self, p, u_fine, travel, first, horizon: int, n_sub: int, averaged: bool, receiver):
        """:meth:`run_windows` as a Python loop over the fine steps, each one :meth:`step`."""
        W, C = p.shape
        out = np.zeros((W, horizon, C))
        acc = np.zeros((W, C))
        last = travel.shape[0] - 1
        for step in range(horizon * n_sub):
            f = first + step
            self.follow_supply(receiver, f)
            p = self.step(p, u_fine[f], travel[f], travel[np.minimum(f + 1, last)])
            acc += p
            if (step + 1) % n_sub == 0:
                out[:, (step + 1) // n_sub - 1] = acc / n_sub if averaged else p
                acc[:] = 0
        return out

    def areas(self, u, cs=slice(None)):
        """(supply, exhaust) valve areas (W, C) [m^2] at commands u (W, C) [V] of the chambers
        ``cs`` (default all): :func:`model_areas`."""
        return model_areas(self.tab, self.mods, u, cs)

    def kernel_args(self) -> tuple:
        """The compiled step's packed arguments for these mods (chamber_kernel.step_batch's from
        ``rows`` to ``tube_tau_s``, without the windows' pressures, commands, travels, gas
        temperatures, supply shifts and tube pressures); the supply flow's array
        (SUPPLY_FLOW_ARG) is a state the kernel updates."""
        return self._kernel_args

    def kernel_glob(self) -> np.ndarray:
        """The compiled step's gas and plant constants (pneumatics.kernel.pack_glob's array)."""
        return self._kernel_args[17]

    def start_tubes(self, exp: Experiment, u_fine: np.ndarray, first: np.ndarray) -> None:
        """The lumped lines' tube pressures where the windows start (fine steps ``first`` (W,)),
        ``u_fine`` (F, C) every chamber's effective commands (tubes.start_tubes)."""
        start_tubes(self, exp, u_fine, first)

    def start_supply(self, exp: Experiment, u_fine: np.ndarray, first: np.ndarray) -> np.ndarray | None:
        """The supply's states where the windows start (fine steps ``first`` (W,)): the
        reservoir form's low-passed flow; returns the compressor's receiver path (F,) [Pa],
        None without one (:meth:`follow_supply` reads it every step)."""
        mods = self.mods
        if has_droop(mods) and mods.supply_droop_tau_s > 0:
            self.set_supply_flow(filtered_supply_flow(exp, self, u_fine)[first])
        return receiver_trajectory(exp, self, u_fine)

    def follow_supply(self, receiver: np.ndarray | None, f: np.ndarray) -> None:
        """Each window's supply pressure at its fine step f (W,) from the receiver's path."""
        if receiver is not None:
            self.supply_shift[: f.size] = receiver[np.minimum(f, receiver.size - 1)] - self.tab.supply_pa

    def set_supply_flow(self, total_kg_s: np.ndarray) -> None:
        """Start every window's low-passed supply flow (the reservoir form's state) at
        ``total_kg_s`` (W,) [kg/s]."""
        W = total_kg_s.size
        self._kernel_args[SUPPLY_FLOW_ARG][:W] = total_kg_s
        self.m_supply_total[:W, 0] = total_kg_s

    def step_reference(self, p, u, travel0, travel1):
        """The numpy reference of :meth:`step` (every chamber)."""
        if self.chambers is not None:
            raise ValueError("step_reference steps every chamber; this model steps some of them")
        tab, mods, gas = self.tab, self.mods, self.gas
        W = p.shape[0]
        a_s, a_e = self.areas(u)
        vol = self.dead + tab.area * 0.5 * (travel0 + travel1)
        vdot = tab.area * (travel1 - travel0) / FINE_DT
        droop = has_droop(mods)
        ps = (tab.supply_pa - droop_pa(self.m_supply_total, mods.supply_droop_pa_per_kg_s, mods.supply_droop_pa_per_kg2_s2)
              if droop else tab.supply_pa)
        ps = ps + self.supply_shift[:W, None]
        room, rt, n = tab.room_pa, self.rt, self.n

        def rhs(q):
            m_s, _, dms = orifice_flow(a_s, ps, q, gas)
            m_e, dme, _ = orifice_flow(a_e, q, room, gas)
            m = m_s - m_e
            dm = dms - dme
            m_x, dmx = mods.external_leak_flow(q, room, gas)
            m_c, dmc = mods.valve_clearance_flow(u, tab.valve[:, 0], q, ps, room)
            m = m - m_x + m_c
            dm = dm - dmx + dmc
            if mods.piston_leak_m2 is not None or mods.piston_leak_g is not None:
                m_ab, dab_a, dab_b = mods.piston_leak_flow(q, room, gas)  # a -> b
                m = m.copy()
                dm = dm.copy()
                m[:, 0::2] -= m_ab
                m[:, 1::2] += m_ab
                dm[:, 0::2] -= dab_a
                dm[:, 1::2] += dab_b
            cap = capacity(vol, q, room, n, mods.wall_compliance_m3_pa)
            return n / cap * (rt * m - q * vdot), n / cap * (rt * dm - vdot), m_s

        f0, jac, m_s = rhs(p)
        denom = 1.0 - GAMMA * FINE_DT * jac
        k1 = f0 / denom
        f1, _, _ = rhs(p + FINE_DT * k1)
        k2 = (f1 - 2.0 * k1) / denom
        p_new = p + 1.5 * FINE_DT * k1 + 0.5 * FINE_DT * k2
        bad = ~np.isfinite(p_new) | (p_new <= 0)
        if bad.any():
            p_new = np.where(bad, p, p_new)
        if self.thermal.size:
            p_new = self._thermal_step(p, p_new, u, a_s, a_e, vol, vdot, ps)
        if has_tubes(mods):
            p_new = tube_step_reference(self, p, p_new, u, a_s, a_e, vol, vdot, ps)
        if droop:
            self.m_supply_total = filtered_flow(self.m_supply_total, np.maximum(m_s, 0).sum(axis=1, keepdims=True),
                                                mods.supply_droop_tau_s, FINE_DT)
        return p_new

    def _thermal_step(self, p, p_new, u, a_s, a_e, vol, vdot, ps):
        """The heat_transfer chambers by the energy equation (pneumatics.effects.heat_transfer)."""
        cs, mods, tab = self.thermal, self.mods, self.tab
        extra = mods.chamber_leak_flow(p, tab.room_pa, self.gas)
        extra += mods.valve_clearance_flow(u, tab.valve[:, 0], p, ps, tab.room_pa)[0]
        p_th, t_th = thermal_step(p[:, cs], self.T[:, cs], vol[:, cs], vdot[:, cs], a_s[:, cs], a_e[:, cs],
                                  self.gas, ps, tab.room_pa, mods.heat_w_k[cs], self.gas.temperature_k,
                                  FINE_DT, extra[:, cs])
        p_new = p_new.copy()
        p_new[:, cs] = p_th
        self.T[:, cs] = t_th
        return p_new


def capacity(vol, p, room_pa, n, wall_compliance):
    """The volume [m^3] that divides n (R T mdot - p dV/dt) in dp/dt: ``vol`` with a rigid wall;
    with a compliant one (V = vol + C (p - p_room), so dV/dt carries C dp/dt) the wall's
    volume and n p C beside it (paper 002 eq. 9 with V a function of p)."""
    if wall_compliance is None:
        return vol
    return vol + wall_compliance * (p - room_pa) + n * p * wall_compliance


#: the cylinder force [N], as a fraction of its largest (bore area x supply gauge), over which the
#: piston crosses the play when the force reverses (a smooth sign: the crossing takes a few ms)
BACKLASH_FORCE_FRACTION = 0.01


def drive_side_lengths(exp: Experiment, mods: PneumaticMods) -> np.ndarray:
    """(F, n_act) actuator lengths on the 1 ms grid seen by the chambers.

    With backlash the piston is not where the link angle puts it: it leads the link by half the
    play on the side it pushes, q_drive = q + gap/2 sign(F) (Nordin & Gutman 2002, dead zone in
    contact), F the cylinder force from the measured pressures; joint transmissions only
    (length = gear q)."""
    if mods.backlash_rad is None or not np.any(mods.backlash_rad > 0):
        return exp.fine_length
    robot, tab = exp.robot, exp.robot.tables
    from pneumatics.chamber import actuator_force
    force = actuator_force(tab, fine_pressures(exp, mods))
    width = BACKLASH_FORCE_FRACTION * tab.area_a * (tab.supply_pa - tab.room_pa)
    gear = robot.model.actuator_gear[robot.actuator_ids, 0]
    return exp.fine_length + gear * 0.5 * mods.backlash_rad * np.tanh(force / width)


def initial_pressure(exp: Experiment, k0, mods: PneumaticMods):
    """Pressures at sample times t[k0] (W, C) from the light smoothing spline of the measured
    pressures (the DAQ means stand half a period earlier); remove a modelled sensor offset."""
    p0 = exp.p_at_t[k0].copy()
    offset = mods.sensor_offsets(exp.clock_at()[k0])
    if offset is not None:
        p0 = p0 - offset
    return p0


def model_areas(tab, mods: PneumaticMods, u: np.ndarray, cs=slice(None)):
    """(supply, exhaust) valve areas [m^2] at commands u (..., C) [V] of the chambers ``cs``
    (default all) under the chamber model: the valve map (the table's rows broadcast over the
    leading axes), the calibration's scales and the valve leaks."""
    a_s, a_e = valve_areas(u, tab.valve[cs])
    leak_s, leak_e = mods.valve_leak_areas(u, tab.valve[cs, 0], cs)
    return a_s * mods.supply_scale[cs] + leak_s, a_e * mods.exhaust_scale[cs] + leak_e


def filtered_supply_flow(exp: Experiment, model: ChamberModel, u_fine: np.ndarray) -> np.ndarray:
    """(F,) the total supply flow [kg/s] on the 1 ms grid, low-passed with the reservoir form's
    time constant (effects.supply_droop, backward Euler as the step's), at the measured
    pressures and the nominal supply: the receiver's state where a replay window starts (a
    window started from no flow would see the nominal supply for a time constant)."""
    return reservoir_flow(measured_supply_flow(exp, model, u_fine, model.tab.supply_pa), model.mods.supply_droop_tau_s)


def reservoir_flow(total_kg_s: np.ndarray, tau_s: float) -> np.ndarray:
    """(F,) the total supply flow [kg/s] on the 1 ms grid low-passed with the reservoir form's
    time constant ``tau_s`` (effects.supply_droop.filtered_flow's backward Euler, started at the
    first flow); tau_s = 0: the flow itself."""
    if tau_s <= 0:
        return total_kg_s
    a = FINE_DT / (tau_s + FINE_DT)
    return lfilter([a], [1.0, a - 1.0], total_kg_s, zi=[(1.0 - a) * total_kg_s[0]])[0]


def chambers_independent(mods: PneumaticMods, exps=()) -> bool:
    """Whether each cylinder's chambers replay independently of the others' under ``mods`` on
    the experiments ``exps``: no supply pressure that falls with their summed flow
    (supply_droop) and no compressor's receiver integrated from it -- a receiver whose path the
    model holds for each of ``exps`` (receiver.held_path) gives every window its supply
    pressure whatever the chambers draw.  The valves, leaks, volumes, gas temperatures and
    sensors are each chamber's own; a piston leak joins a cylinder's two chambers."""
    if has_droop(mods):
        return False
    return compressor_of(mods) is None or (bool(exps) and all(held_path(mods, e) is not None for e in exps))


def has_droop(mods: PneumaticMods) -> bool:
    """Whether the supply pressure falls with the total flow (supply_droop, linear, reservoir or
    regulator_orifice form)."""
    return mods.supply_droop_pa_per_kg_s > 0 or mods.supply_droop_pa_per_kg2_s2 > 0


def cylinder_chambers(chambers) -> np.ndarray:
    """The chambers of the cylinders that ``chambers`` (indices) belong to, a and b in turn."""
    cyl = sorted({int(c) // 2 for c in chambers})
    return np.array([c for j in cyl for c in (2 * j, 2 * j + 1)], int)


def replay(exp: Experiment, win: Windows, mods: PneumaticMods, chambers: np.ndarray | None = None):
    """Predicted DAQ pressures at samples starts+1 .. starts+H, with the measured ones.

    Returns (predicted, measured), each (W, H, C) [Pa].  ``chambers``: whole cylinders'
    chambers (:func:`cylinder_chambers`) replayed alone, (W, H, len(chambers)), where
    :func:`chambers_independent` holds: the same numbers as their columns of the whole replay
    at a fraction of its cost on a robot of many cylinders."""
    W, H, S = win.starts.size, win.horizon, exp.n_sub
    if chambers is not None and not chambers_independent(mods, (exp,)):
        raise ValueError("these chambers share a supply whose pressure follows all their flows: replay them all")
    cols = slice(None) if chambers is None else np.asarray(chambers, int)
    model = ChamberModel(exp.robot, mods, W, None if chambers is None else cols)
    u_all = effective_commands(exp, mods)
    u_f = u_all[:, cols]
    travel = model.travel(drive_side_lengths(exp, mods), cols)  # (F, C)
    k0 = win.starts
    p = initial_pressure(exp, k0, mods)[:, cols]
    if model.thermal.size:
        model.T = np.ascontiguousarray(gas_temperatures(exp, mods, u_all)[k0 * S][:, cols])
    receiver = model.start_supply(exp, u_all, k0 * S)
    model.start_tubes(exp, u_all, k0 * S)
    out = model.run_windows(p, u_f, travel, k0 * S, H, S, exp.averaged, receiver)
    idx = k0[:, None] + 1 + np.arange(H)[None]
    offset = mods.sensor_offsets(exp.clock_at()[idx])
    if offset is not None:
        out = out + np.broadcast_to(offset, idx.shape + (exp.robot.tables.n_chambers,))[..., cols]
    return out, exp.p[idx][..., cols]
