"""Each chamber's pressure between the samples, for the rigid body's replays
(angle_replay.pressure_driven_angles): a Kalman smoother whose process is the chamber model over
one sample interval and whose measurement is the DAQ's mean over it.

The replays push the rigid body with the cylinders' forces on a 1 ms grid; a recording holds
the pressures' 100 Hz DAQ means.  Under humanoid38's PIDF every joint limit-cycles at 9-14 Hz
with harmonics past the 50 Hz Nyquist frequency, and the valve commands step at every sample:
a cubic through the samples (data.fine_pressures) missed the simulator's own 1 ms pressures by
4.8 kPa rms on a development recording (seed 7100, nominal humanoid38 with +-3 % errors, 60 s),
by 6.3 kPa at the sample instants themselves.  The chamber model knows what the samples do
not: each valve's flow at the command held over the interval, and the volume the measured
motion sweeps.

**Method.** Chambers replay independently given the measured motion and commands (as the
pressure replays do), so each is one scalar state-space model with state x_k = p(t_k):

    x_{k+1} = phi_k(x_k) + w_k,     w_k ~ N(0, q),   q = (PROCESS_SD_PA)^2 per 100 Hz interval
    z_k     = mu_k(x_k) + v_k,      v_k ~ N(0, r),   r = the sensors' noise squared (measurement_sd)

where phi_k integrates the chamber equations (pneumatic.ChamberModel, the calibrated ``mods``)
over [t_k, t_{k+1}] from x_k with the commands held and the measured lengths, and z_k is the
DAQ mean over that interval (row k + 1; the end pressure when the DAQ does not average).  Both
are linearised about the light spline's pressures at the sample times (``exp.p_at_t``): phi, mu
and their slopes from two replays of every interval at once, from x and x + SLOPE_STEP_PA.  A
Kalman filter forward and the Rauch-Tung-Striebel smoother backward (Rauch, Tung & Striebel,
AIAA J. 3(8), 1965; the extended form linearised about a reference trajectory: Sarkka,
*Bayesian Filtering and Smoothing*, 2013, ch. 5 and 9) give the sample-instant pressures; each
interval is then replayed from its smoothed start and the gap to the next start (the process
noise's draw) spread linearly over it.  On seed 7100 against the simulator's 1 ms pressures:
1.7 kPa rms (process s.d. 300 / 1000 / 3000 Pa: 2.1 / 1.7 / 1.8 kPa); linearised again about
the smoothed states, the same to 1 Pa.  A join of pooled recordings cuts the chain there.
"""
from __future__ import annotations

import hashlib
from dataclasses import fields

import numpy as np

from .calibrate import pressure_sigma
from .data import Experiment
from .pneumatic import ChamberModel, drive_side_lengths, effective_commands
from .pneumatic_mods import PneumaticMods
from .thermal import gas_temperatures

#: the chamber model's error over one 100 Hz sample interval, a standard deviation [Pa] (scaled
#: as a random walk for other rates); see the module's docstring for how it was chosen
PROCESS_SD_PA = 1000.0
#: the step from which each interval's slopes d phi / dx, d mu / dx are taken [Pa]
SLOPE_STEP_PA = 100.0
#: the first state's prior standard deviation about the light spline's value [Pa]
PRIOR_SD_PA = 1e4
#: the sensor-offset fields of PneumaticMods: the smoother runs on the pressures as read, and
#: the replays take the offsets off afterwards (first order: a few kPa change the flows little)
SENSOR_FIELDS = ("sensor_offset_pa", "sensor_drift_pa", "sensor_drift_tau_s")
#: smoothed pressures kept per recording (a doctor's run asks for the same ones hundreds of times)
CACHE_SIZE = 4


def smoothed_pressures(exp: Experiment, mods: PneumaticMods) -> np.ndarray:
    """(F, C) every chamber's pressure [Pa] on the 1 ms grid as read (sensor offsets not taken
    off), smoothed as the module's docstring says with the chamber model ``mods``; kept on
    ``exp`` for the next call with the same recording and chamber model."""
    cache, key = exp.smoothed_cache, mods_key(mods)
    for entry in cache:     # a copy of ``exp`` (dataclasses.replace) shares the list
        if entry[0] == key and entry[1] is exp.p and entry[2] is exp.u and entry[3] is exp.fine_length:
            return entry[4]
    out = _smooth(exp, mods)
    cache.append((key, exp.p, exp.u, exp.fine_length, out))
    del cache[:-CACHE_SIZE]
    return out


def mods_key(mods: PneumaticMods) -> str:
    """A digest of everything in ``mods`` the chamber model integrates (the sensor offsets not)."""
    h = hashlib.sha1()
    for f in fields(mods):
        if f.name in SENSOR_FIELDS:
            continue
        v = getattr(mods, f.name)
        items = sorted(v.items()) if isinstance(v, dict) else [(None, v)]
        for k, x in items:
            h.update(f"{f.name}:{k}:".encode())
            h.update(np.ascontiguousarray(x, float).tobytes() if x is not None else b"None")
    return h.hexdigest()


def _smooth(exp: Experiment, mods: PneumaticMods) -> np.ndarray:
    """The smoothed 1 ms pressures (:func:`smoothed_pressures`), computed."""
    mods = mods.copy(**{name: None for name in SENSOR_FIELDS})
    S, N = exp.n_sub, exp.t.size
    ref = exp.p_at_t
    intervals = np.arange(N - 1)
    both = interval_paths(exp, mods, np.concatenate([ref[:-1], ref[:-1] + SLOPE_STEP_PA]), np.tile(intervals, 2))
    path, plus = both[:N - 1], both[N - 1:]
    phi, mu = _end_and_mean(path, exp.averaged)
    phi_up, mu_up = _end_and_mean(plus, exp.averaged)
    cut = np.zeros(N - 1, bool)         # interval k leads into a pooled recording's start
    cut[np.asarray(exp.breaks, int) - 1] = True
    F, H = (phi_up - phi) / SLOPE_STEP_PA, (mu_up - mu) / SLOPE_STEP_PA
    q, r = PROCESS_SD_PA ** 2 * (100.0 / exp.rate_hz), measurement_sd(exp) ** 2
    x = rts_smoother(phi, F, mu, H, exp.p[1:], ref, q, r, PRIOR_SD_PA ** 2, cut)
    path = interval_paths(exp, mods, x[:-1], intervals)            # (N - 1, S, C) at the fine steps 1..S
    start = np.concatenate([x[:-1, None], path[:, :-1]], axis=1)   # fine steps 0..S-1 of each interval
    gap = x[1:] - path[:, -1]
    fine = start + (np.arange(S) / S)[None, :, None] * gap[:, None, :]
    joined = np.linspace(0.0, 1.0, S, endpoint=False)[None, :, None] * (x[1:] - x[:-1])[:, None, :]
    fine[cut] = x[:-1][cut][:, None, :] + joined[cut]              # across a join: a straight line
    out = np.concatenate([fine.reshape(-1, x.shape[1]), x[-1:]])
    if out.shape[0] != exp.fine_t.size:
        raise ValueError(f"smoothed pressures on {out.shape[0]} fine steps, the recording's grid has {exp.fine_t.size}")
    return out


def measurement_sd(exp: Experiment) -> float:
    """The DAQ means' noise [Pa]: the robot's pressure sensors' as its fluid.toml states it
    (``[sensors] pressure_noise_pa``), or the noise floor from the data's third differences
    (calibrate.pressure_sigma) where that is lower.  The data's floor alone counts a fast limit
    cycle as noise (seed 7100: 1980 Pa against the sensors' 474), and a smoother that trusts
    the samples four times too little missed the simulator's 1 ms pressures by 2.3 kPa rms, not
    1.7; the likelihood of the filter's innovations did not single out the sensors' noise
    either (its choice per chamber spread from 124 to 1980 Pa: the chamber model's errors are
    not white)."""
    return max(min(float(exp.robot.fluid.sensors.pressure_noise_pa), pressure_sigma(exp)), 1.0)


def interval_paths(exp: Experiment, mods: PneumaticMods, x: np.ndarray, intervals: np.ndarray) -> np.ndarray:
    """(M, S, C) the chamber pressures [Pa] at the fine steps 1..S of sample intervals
    ``intervals`` (M,), each replayed from ``x`` (M, C) at its start with the commands and
    lengths measured (all at once: pneumatic.replay's set-up with one-sample windows on the
    1 ms grid)."""
    S = exp.n_sub
    first = np.asarray(intervals, int) * S
    model = ChamberModel(exp.robot, mods, x.shape[0])
    u_all = effective_commands(exp, mods)
    travel = model.travel(drive_side_lengths(exp, mods))
    if model.thermal.size:
        model.T = np.ascontiguousarray(gas_temperatures(exp, mods, u_all)[first])
    receiver = model.start_supply(exp, u_all, first)
    model.start_tubes(exp, u_all, first)
    out = np.empty((x.shape[0], S, x.shape[1]))
    p = np.array(x, float)
    for s in range(S):        # ChamberModel.run_windows_reference's loop (its compiled twin is slower here)
        f = first + s
        model.follow_supply(receiver, f)
        p = out[:, s] = model.step(p, u_all[f], travel[f], travel[f + 1])
    return out


def _end_and_mean(path: np.ndarray, averaged: bool) -> tuple[np.ndarray, np.ndarray]:
    """(pressure at each interval's end, what the DAQ reads of it: the mean, or the end)."""
    end = path[:, -1]
    return end, (path.mean(axis=1) if averaged else end)


def rts_smoother(phi, F, mu, H, z, ref, q, r, p0: float, cut) -> np.ndarray:
    """(N, C) the smoothed states of N scalar chains (one per column), linearised about
    ``ref`` (N, C): x_{k+1} = phi_k + F_k (x_k - ref_k) + w (variance q), z_k = mu_k + H_k
    (x_k - ref_k) + v (variance r), k < N - 1 (each (N - 1, C)); x_0 ~ N(ref_0, p0); where
    ``cut`` (N - 1,) the chain restarts at k + 1 from N(ref_{k+1}, p0) and z_k is not of x_k.
    Kalman filter, then the Rauch-Tung-Striebel recursion backward."""
    N, C = ref.shape
    xp, pp = np.empty((N, C)), np.empty((N, C))     # predicted
    xf, pf = np.empty((N, C)), np.empty((N, C))     # filtered
    xp[0], pp[0] = ref[0], p0
    for k in range(N - 1):
        if cut[k]:      # the mean read at k + 1 is of the period before the next recording's start
            xf[k], pf[k] = xp[k], pp[k]
            xp[k + 1], pp[k + 1] = ref[k + 1], p0
            continue
        gain = pp[k] * H[k] / (H[k] ** 2 * pp[k] + r)
        xf[k] = xp[k] + gain * (z[k] - mu[k] - H[k] * (xp[k] - ref[k]))
        pf[k] = (1.0 - gain * H[k]) * pp[k]
        xp[k + 1] = phi[k] + F[k] * (xf[k] - ref[k])
        pp[k + 1] = F[k] ** 2 * pf[k] + q
    xf[-1], pf[-1] = xp[-1], pp[-1]
    xs = xf.copy()
    for k in range(N - 2, -1, -1):
        if not cut[k]:
            xs[k] = xf[k] + pf[k] * F[k] / pp[k + 1] * (xs[k + 1] - xp[k + 1])
    return xs
