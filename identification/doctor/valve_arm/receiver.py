"""The supply_droop effect's compressor_cycling form in the doctor's replays: the receiver's
pressure along a recording.

A receiver filled by a switched compressor and drained by the valves and the system's leak
(pneumatics.effects.supply_droop.receiver_step, Beater 2007 ch. 2).  Its pressure cannot be
replayed from a window's start, as the chambers' are: it keeps no sensor, and its phase in the
switch's cycle at any moment depends on the whole history.  So the doctor integrates it once
along each recording, the valves drawing their flows at the measured chamber pressures, from
a start state fitted to that recording (supply_receiver), and every replay window reads the
supply pressure from that path.
"""
from __future__ import annotations

import numpy as np

from pneumatics.effects.supply_droop import CompressorCycling
from pneumatics.medium import orifice_flow

try:
    from numba import njit
except ImportError:  # pragma: no cover - numba is a dependency; the reference then runs
    njit = None

from .data import FINE_DT, Experiment, fine_pressures
from .supply_shares import SupplyShares


def experiment_key(exp: Experiment) -> str:
    """A recording set's key in PneumaticMods.receiver_paths: its first time, length and
    first pressures (a corrected copy of the experiment keeps them)."""
    return f"{exp.t[0]:.6f}/{exp.t.size}/{exp.p[0, 0]:.3f}"


def segment_starts(exp: Experiment, n_sub: int = 1) -> np.ndarray:
    """Indices (on a grid of n_sub points per sample) where each pooled recording starts."""
    return np.array([0, *[b * n_sub for b in exp.breaks]], np.int64)


def compressor_of(mods) -> CompressorCycling | None:
    """The compressor_cycling form the chamber model ``mods`` carries, None without one."""
    if not mods.supply_receiver_m3 > 0:
        return None
    return CompressorCycling(mods.supply_receiver_m3, mods.supply_compressor_kg_s, mods.supply_band_pa,
                             mods.supply_cut_out_pa, mods.supply_leak_kg_s_pa)


def _advance(p, running, h, total, volume, delivery, band, cut_out, leak, rt, room):
    """(pressure, running) of the receiver h [s] on at a held total draw: the switch flips at
    the moment the pressure reaches its limit inside the step (not at the step's end), so a
    path of 0.1 s steps switches when one of 1 ms steps does and a cycle's period does not
    depend on the step (an end-of-step switch overshoots by a step's rise every time)."""
    for _ in range(8):  # at most a few switches inside one step
        if p >= cut_out:
            running = 0.0
        elif p <= cut_out - band:
            running = 1.0
        rate = rt / volume * (delivery * running - total - leak * (p - room))
        limit = cut_out if (running > 0.0 and rate > 0.0) else (cut_out - band if (running == 0.0 and rate < 0.0) else p)
        t_hit = (limit - p) / rate if rate != 0.0 else h
        if limit != p and 0.0 < t_hit < h:
            p, h = limit, h - t_hit
        else:
            return p + rate * h, running
    return p, running


def path_reference(total, dt, c: CompressorCycling, starts, p0, run0, rt, room):
    """(n,) the receiver's pressure [Pa] at each point (before its step) of a path whose
    step k lasts dt[k] [s] with the valves drawing total[k] [kg/s]; at the indices ``starts``
    it restarts at pressure p0[i], running run0[i] (effects.supply_droop.receiver_step's law,
    switching inside a step, :func:`_advance`).  The readable twin of :func:`path`."""
    out = np.empty(len(total))
    p, running, seg = 0.0, 0.0, 0
    for k in range(len(total)):
        if seg < len(starts) and k == starts[seg]:
            p, running, seg = float(p0[seg]), float(run0[seg]), seg + 1
        out[k] = p
        p, running = _advance(p, running, float(dt[k]), float(total[k]), c.receiver_volume_m3, c.compressor_kg_s,
                              c.band_pa, c.cut_out_pa, c.leak_kg_s_pa, rt, room)
    return out


def _path(total, dt, volume, delivery, band, cut_out, leak, starts, p0, run0, rt, room, out):
    p, running, seg = 0.0, 0.0, 0
    for k in range(total.size):
        if seg < starts.size and k == starts[seg]:
            p, running, seg = p0[seg], run0[seg], seg + 1
        out[k] = p
        p, running = _advance_compiled(p, running, dt[k], total[k], volume, delivery, band, cut_out, leak, rt, room)
    return out


_advance_compiled = njit(cache=True)(_advance) if njit is not None else _advance
_path_compiled = njit(cache=True)(_path) if njit is not None else _path


def path(total, dt, c: CompressorCycling, starts, p0, run0, rt, room) -> np.ndarray:
    """:func:`path_reference`, compiled (a few microseconds per thousand steps)."""
    return _path_compiled(np.ascontiguousarray(total, float), np.ascontiguousarray(dt, float), float(c.receiver_volume_m3),
                          float(c.compressor_kg_s), float(c.band_pa), float(c.cut_out_pa), float(c.leak_kg_s_pa),
                          np.asarray(starts, np.int64), np.asarray(p0, float), np.asarray(run0, float), float(rt),
                          float(room), np.empty(len(total)))


def held_path(mods, exp: Experiment) -> np.ndarray | None:
    """(F,) the receiver's pressure [Pa] along ``exp`` that the chamber model ``mods`` holds
    (``receiver_paths``, as the receiver's fit left it), None where it holds none as long."""
    held = (mods.receiver_paths or {}).get(experiment_key(exp))
    return held if held is not None and held.size >= exp.fine_t.size - 1 else None


def measured_supply_flow(exp: Experiment, model, u_fine: np.ndarray, supply_pa) -> np.ndarray:
    """(F,) the total flow [kg/s] the valves draw on the 1 ms grid at the measured pressures
    (sensor offsets of the model removed) from a supply at ``supply_pa`` (scalar or (F,)).
    From a scalar supply each chamber's share is kept on ``exp`` and recomputed only where its
    inputs changed (supply_shares.SupplyShares; the same sum as
    :func:`measured_supply_flow_reference`'s)."""
    if np.isscalar(supply_pa):
        if exp.supply_shares is None:
            exp.supply_shares = SupplyShares()
        return exp.supply_shares.total(exp, model, u_fine, supply_pa)
    return measured_supply_flow_reference(exp, model, u_fine, supply_pa)


def measured_supply_flow_reference(exp: Experiment, model, u_fine: np.ndarray, supply_pa) -> np.ndarray:
    """:func:`measured_supply_flow` computed whole: every chamber's flow at every call."""
    p = fine_pressures(exp, model.mods)
    a_s, _ = model.areas(u_fine[: p.shape[0]])
    ps = supply_pa if np.isscalar(supply_pa) else np.asarray(supply_pa)[: p.shape[0], None]
    return np.maximum(orifice_flow(a_s, ps, p, model.gas)[0], 0.0).sum(axis=1)


def receiver_trajectory(exp: Experiment, model, u_fine: np.ndarray) -> np.ndarray | None:
    """(F,) the supply pressure [Pa] on the 1 ms grid of ``exp`` under the chamber model's
    compressor (None without one): the path its fit left for this recording set (the model's
    ``receiver_paths``: integrated again under each refitted calibration, a relaxation
    oscillator's phase would drift from the one fitted), else integrated from the cut-out, the
    compressor off, as the simulator starts.  A supply path the model holds in place of its
    supply's laws (``supply_paths``, supply_path.with_held_supply) comes first."""
    held = (model.mods.supply_paths or {}).get(experiment_key(exp))
    if held is not None:
        return held
    c = compressor_of(model.mods)
    if c is None:
        return None
    held = held_path(model.mods, exp)
    if held is not None:
        return held
    starts = segment_starts(exp, exp.n_sub)
    held = [(c.cut_out_pa, False)] * starts.size
    rt = model.gas.gas_constant_j_per_kg_k * model.gas.temperature_k
    supply = model.tab.supply_pa
    for _ in range(2):  # the valves draw from the receiver's pressure: once at the nominal, once at the path's
        total = measured_supply_flow(exp, model, u_fine, supply)
        supply = path(total, np.full(total.size, FINE_DT), c, starts, [h[0] for h in held], [float(h[1]) for h in held],
                      rt, model.tab.room_pa)
    return supply
