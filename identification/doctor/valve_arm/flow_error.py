"""The chambers' mass-flow equation error and the physical inputs a correction of it may use.

A chamber's energy balance with a polytropic exponent n between 1 and 1.4 (paper 002 eq. 9,
dp/dt = n / V (R T mdot - p dV/dt), solved for the mass flow) gives the net mass flow into it
from the measured pressure and motion:

    mdot_implied = (V dp/dt / n + p dV/dt) / (R T),

while the calibrated model (valve orifices, papers 002 eqs. 6-8, 000 eq. 5, and the effects kept
so far) says mdot_model.  Their difference, in block means (MECH_BLOCK_S: the means of a
differentiated noisy signal), is the equation error a flexible correction is fitted to (Ljung
1999, sec. 7.3: equation-error models).  The implied flow's integral over a block needs no
derivative: sum V_mid dp / n + p_mid dV over the 1 ms steps.

The correction's inputs are grouped by the physical quantity they carry; each group is the
subsystem input the families of pneumatics.effects act through (docs/doctor.md):

- ``command near null``: bumps of u - u_null times unit orifice flows from the supply and to
  the room (an underlapped spool leaks where the command is near null);
- ``pressure level``: p - p_room, p^2 - p_room^2 and a unit orifice to the room (leaks out);
- ``p_a - p_b``: the cylinder's two chambers' pressure difference (a leak across the piston);
- ``volume``: V dp/dt, p dV/dt and their low-passed histories (heat exchange, a wrong
  polytropic exponent, a volume the model lacks);
- ``command history``: the model's valve flow at the command low-passed or delayed, minus at
  the command itself (spool dynamics, a line between valve and chamber);
- ``valve opening``: the model's supply and exhaust flows, alone and times the pressure
  (a valve whose areas change with pressure or opening: no library family);
- the supply's common mode: d mdot_supply / d p_supply of every chamber times the total supply
  flow and its low-passed histories (one pressure drop shared by all chambers).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_smoothing_spline
from scipy.signal import lfilter

from identification.base.smoothing import discrepancy_lambda

from pneumatics.effects.line_dynamics import tube_conductance
from pneumatics.effects.supply_droop import droop_pa
from pneumatics.orifice_arrays import orifice_flows
from pneumatics.tube_kernel import tube_path_compiled

from .data import FINE_DT, Experiment, fine_pressures
from .pneumatic import ChamberModel, drive_side_lengths, effective_commands, model_areas
from .pneumatic_mods import PneumaticMods
from .tubes import has_tubes, tube_valve
from .receiver import receiver_trajectory

#: the groups of a chamber's correction, in the order the report lists them
GROUPS = ("command near null", "pressure level", "p_a - p_b", "volume", "command history", "valve opening")
#: widths [V] of the bumps in u - u_null: a narrow and a wide underlap (pneumatics.effects.valve_leak
#: uses 0.6 V)
NULL_WIDTHS_V = (0.3, 0.8)
#: time constants [s] of the command's low-pass and its delays: spools of 10-80 ms, lines of
#: 5-50 ms (pneumatics.effects.valve_dynamics and line_dynamics cover this range)
HISTORY_TAUS_S = (0.01, 0.03, 0.08)
HISTORY_DELAYS_S = (0.02, 0.05)
#: time constants [s] of the volume group's histories: the gas-wall exchange of arm2's chambers
#: relaxes in 0.1-1 s (hA 0.02-0.5 W/K, pneumatics.effects.heat_transfer)
VOLUME_TAUS_S = (0.05, 0.3)
#: ... and of the supply's: a regulator refilling a reservoir (Beater, Pneumatic Drives 2007, ch. 4)
SUPPLY_TAUS_S = (0.05, 0.2, 0.6)


@dataclass
class FlowBlocks:
    """Block means of one experiment: B blocks, C chambers."""

    error: np.ndarray          # (B, C) mdot_implied - mdot_model [kg/s]
    features: dict             # group -> (B, C, k) inputs of each chamber's correction
    supply: np.ndarray         # (B, C, k) the supply's common-mode inputs, per chamber
    sample: np.ndarray         # (B,) sample index at each block's centre
    n_sub: int                 # fine steps per sample
    supply_sensitivity: np.ndarray | None = None   # (B, C) d mdot_supply / d p_supply [kg/(s Pa)]
    supply_total: np.ndarray | None = None         # (B,) the total flow the valves draw from the supply [kg/s]
    fine_start: np.ndarray | None = None           # (B,) each block's first 1 ms step
    fine_len: int = 0                               # 1 ms steps per block


def lowpass(x: np.ndarray, tau_s: float, dt: float = FINE_DT) -> np.ndarray:
    """First-order low-pass along axis 0 started at x[0] (exact for a held input)."""
    a = np.exp(-dt / tau_s)
    return lfilter([1 - a], [1, -a], x, axis=0, zi=a * x[:1])[0]


def delayed(x: np.ndarray, delay_s: float, dt: float = FINE_DT) -> np.ndarray:
    k = int(round(delay_s / dt))
    return np.concatenate([np.repeat(x[:1], k, axis=0), x[:-k]]) if k else x


class _Valves:
    """The calibrated model's valve flows [kg/s] at given commands, on the 1 ms grid."""

    def __init__(self, exp: Experiment, mods: PneumaticMods, p: np.ndarray):
        tab = exp.robot.tables
        self.tab, self.mods, self.p, self.gas = tab, mods, p, tab.gas
        self.ps = np.full((p.shape[0], 1), tab.supply_pa)
        self._droop = float(mods.supply_droop_pa_per_kg_s)
        self._droop2 = float(mods.supply_droop_pa_per_kg2_s2)
        self._droop_tau = float(mods.supply_droop_tau_s)

    def supply_pressure(self, a_s) -> np.ndarray:
        """(F, 1) the supply pressure at the valves [Pa]: the nominal's (or the receiver's),
        less the droop the model's own total supply flow through areas ``a_s`` leaves."""
        ps = self.ps
        if self._droop > 0 or self._droop2 > 0:
            m0 = orifice_flows(a_s, ps, self.p, self.gas, derivatives=False)[0]
            total = np.maximum(m0, 0).sum(axis=1, keepdims=True)
            if self._droop_tau > 0:  # behind a receiver (effects.supply_droop, reservoir form)
                total = lowpass(total, self._droop_tau)
            ps = ps - droop_pa(total, self._droop, self._droop2)
        return ps

    def flows(self, u, derivative: bool = True):
        """(supply flow, exhaust flow), each (F, C) [kg/s], and d supply flow / d p_supply
        (None without ``derivative``)."""
        a_s, a_e = model_areas(self.tab, self.mods, u)
        ps = self.supply_pressure(a_s)
        m_s, d_ps, _ = orifice_flows(a_s, ps, self.p, self.gas, derivatives=derivative)
        m_e = orifice_flows(a_e, self.p, self.tab.room_pa, self.gas, derivatives=False)[0]
        return m_s, m_e, d_ps


def tube_flows(exp: Experiment, mods: PneumaticMods, p: np.ndarray, u_fine: np.ndarray) -> dict:
    """{chamber: (F - 1,) the flow [kg/s] its lumped line's tube passes it over each 1 ms step}
    (line_dynamics, lumped_rc): G (p_t - p) at the steps' midpoints, the tube's pressure p_t
    stepped along the recording against the chamber's measured pressure ``p`` (F, C) with the
    valve at ``u_fine`` (F, C) (pneumatics.tube_kernel.tube_path_compiled, nominal supply)."""
    if not has_tubes(mods):
        return {}
    tab = exp.robot.tables
    model = ChamberModel(exp.robot, mods, 1)
    glob = model.kernel_glob()
    out = {}
    for c in np.nonzero(mods.tube_volume_m3 > 0)[0]:
        v, tau = float(mods.tube_volume_m3[c]), float(mods.tube_time_constant_s[c])
        path = np.empty(p.shape[0])
        tube_path_compiled(np.ascontiguousarray(p[:, c]), *tube_valve(tab, mods, u_fine[:, c], c), v, tau,
                           float(tab.supply_pa), glob, path)
        g = float(tube_conductance(v, tau, model.n, model.rt))
        out[int(c)] = g * (0.5 * (path[1:] + path[:-1]) - 0.5 * (p[1:, c] + p[:-1, c]))
    return out


def smoothed_pressures(exp: Experiment) -> np.ndarray:
    """(F, C) measured pressures on the 1 ms grid: a smoothing spline through the DAQ means at
    the sensor's noise level (discrepancy principle, identification.base.smoothing), so that the
    pressure change over a block carries little of the noise of its two end samples."""
    out = np.empty((exp.fine_t.size, exp.p.shape[1]))
    for c in range(exp.p.shape[1]):
        lam = discrepancy_lambda(exp.t_sensor, exp.p[:, c])
        out[:, c] = make_smoothing_spline(exp.t_sensor, exp.p[:, c], lam=lam)(exp.fine_t)
    return out


def flow_blocks(exp: Experiment, mods: PneumaticMods, block: int) -> FlowBlocks:
    """The equation error and the correction's inputs of ``exp`` under the chamber model
    ``mods``, in means over ``block`` samples (blocks straddling a pooled join are dropped)."""
    tab, gas = exp.robot.tables, exp.robot.tables.gas
    S = exp.n_sub
    F = exp.fine_t.size
    p = fine_pressures(exp, mods)
    model = ChamberModel(exp.robot, mods, 1)
    vol = model.dead + tab.area * model.travel(drive_side_lengths(exp, mods))       # (F, C)
    rt, n, room = model.rt, model.n, tab.room_pa
    # per 1 ms step i -> i+1: midpoint values and increments
    p_mid, v_mid = 0.5 * (p[1:] + p[:-1]), 0.5 * (vol[1:] + vol[:-1])
    dp, dv = np.diff(p, axis=0) / FINE_DT, np.diff(vol, axis=0) / FINE_DT
    implied = (v_mid * dp / n + p_mid * dv) / rt
    valves = _Valves(exp, mods, p_mid)
    u_all = effective_commands(exp, mods)
    u_eff = u_all[: F - 1]
    receiver = receiver_trajectory(exp, model, u_all)
    if receiver is not None:  # a compressor's receiver: the supply pressure along the recording
        valves.ps = receiver[: F - 1, None]
    m_s, m_e, d_ps = valves.flows(u_eff)
    leak_x = mods.external_leak_flow(p_mid, room, gas)[0]
    # the lands' clearance flows from the drooped supply, as the replays' (chamber_kernel)
    ps_valves = valves.ps if mods.valve_clearance_g is None else valves.supply_pressure(model_areas(tab, mods, u_eff)[0])
    m_model = m_s - m_e - leak_x + mods.valve_clearance_flow(u_eff, tab.valve[:, 0], p_mid, ps_valves, room)[0]
    for c, m_tube in tube_flows(exp, mods, p, u_all).items():  # a lumped line: its tube feeds the chamber
        m_model[:, c] = m_tube - leak_x[:, c] if np.ndim(leak_x) else m_tube - leak_x
    if mods.piston_leak_m2 is not None or mods.piston_leak_g is not None:
        m_ab = mods.piston_leak_flow(p_mid, room, gas)[0]
        m_model = m_model.copy()
        m_model[:, 0::2] -= m_ab
        m_model[:, 1::2] += m_ab
    # block means over ``block`` samples = block * S fine steps, dropping those across a join
    L = block * S
    nb = (F - 1) // L
    starts = np.arange(nb) * L
    ok = np.ones(nb, bool)
    for b in exp.breaks:
        ok &= ~((starts <= b * S) & (b * S < starts + L + S))
    idx = np.nonzero(ok)[0]

    def bm(x):
        y = x[: nb * L].reshape(nb, L, *x.shape[1:]).mean(axis=1)
        return y[idx]
    feats = _chamber_features(exp, valves, u_eff, p_mid, v_mid, dp, dv, m_s, m_e, S, bm)
    total = np.maximum(m_s, 0).sum(axis=1)
    return FlowBlocks(bm(implied - m_model), feats, _supply_features(total, d_ps, bm),
                      (starts[idx] + L // 2) // S, S, bm(d_ps), bm(total), starts[idx], L)


def _chamber_features(exp, valves, u_eff, p, v, dp, dv, m_s, m_e, S, bm) -> dict:
    """group -> (B, C, k) block means (``bm``) of each chamber's correction inputs on the 1 ms
    grid, each input reduced as soon as it is made: on a 60 s recording of humanoid38 one input
    is a 36 MB array, and all of them side by side took 2 GB."""
    tab, gas = exp.robot.tables, exp.robot.tables.gas
    room, ps = tab.room_pa, tab.supply_pa
    u = np.repeat(exp.u, S, axis=0)[: p.shape[0]]
    du = u - tab.valve[:, 0]
    f_sup = orifice_flows(1.0, ps, p, gas, derivatives=False)[0]
    f_out = orifice_flows(1.0, p, room, gas, derivatives=False)[0]
    near = []
    for w in NULL_WIDTHS_V:
        bump = np.exp(-(du / w) ** 2)
        near += [bm(bump * f_sup), bm(bump * f_out)]
    other = p.reshape(p.shape[0], -1, 2)[:, :, ::-1].reshape(p.shape)       # chamber b of a, a of b
    cross = orifice_flows(1.0, p, other, gas, derivatives=False)[0]
    # the motion's compression p dV/dt and its histories; not V dp/dt, which carries the
    # measured pressure's noise the target carries too (errors in variables)
    pdv = p * dv
    volume = [bm(pdv)] + [bm(lowpass(pdv, t) - pdv) for t in VOLUME_TAUS_S]
    m0 = m_s - m_e
    history = []
    for t in HISTORY_TAUS_S:
        a, b, _ = valves.flows(lowpass(u_eff, t), derivative=False)
        history.append(bm(a - b - m0))
    for d in HISTORY_DELAYS_S:
        a, b, _ = valves.flows(delayed(u_eff, d), derivative=False)
        history.append(bm(a - b - m0))
    rel = (p - room) / (ps - room)
    return {"command near null": np.stack(near, axis=2),
            "pressure level": np.stack([bm(p - room), bm((p ** 2 - room ** 2) / ps), bm(f_out)], axis=2),
            "p_a - p_b": np.stack([bm(p - other), bm(cross)], axis=2),
            "volume": np.stack(volume, axis=2),
            "command history": np.stack(history, axis=2),
            "valve opening": np.stack([bm(m_s), bm(m_e), bm(m_s * rel), bm(m_e * rel)], axis=2)}


def _supply_features(total, d_ps, bm) -> np.ndarray:
    """(B, C, k) block means (``bm``): a supply pressure error common to all chambers, modelled
    as a constant, the total supply flow ``total`` (F-1,) and its low-passed histories, acting on
    each chamber through its own d mdot_supply / d p_supply (a linearised orifice, paper 002 eq. 6)."""
    total = total[:, None]                                                  # (F-1, 1)
    drivers = [total] + [lowpass(total, t) for t in SUPPLY_TAUS_S]
    return np.stack([bm(d_ps * z) for z in drivers], axis=2)
