"""Restarted replays of the elbow's oil side, driven by the measured current and vane motion.

The hydraulic doctor splits the plant where the sensors cut it (as the valve_arm doctor replays
its chambers from the measured motion):

* **oil side** (this module): valve current -> Jiles-Atherton hysteresis (paper 001 eqs. 2-3,
  :class:`pneumatics.hydraulics.hysteresis.Hysteresis`) -> valve tip (eq. 4, exact zero-order
  hold) -> the simulator's own compiled circuit step (``pneumatics.hydraulics.kernel.step_kernel``:
  orifice flows eq. 5, clearance leakage eqs. 11-12, supply and return lines eqs. 6-7 and 10,
  chambers eqs. 8-9) with the vane angle and velocity taken from the measured angle (a
  smoothing spline cut at ``SMOOTH_HZ``, :mod:`identification.base.smoothing`).  Chamber pressures are restarted
  from the measured ones (minus any hypothesised sensor offset) every ``RESTART_S``; the
  valve, the hysteresis and the supply and return lines run on, from the null state;
* **mechanical side** (:mod:`.mechanics`): the vane and load equations with the measured
  pressures and torque.

The first ``BURN_IN_S`` of each trace (hysteresis memory and lines not yet set) is not scored.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.linalg import expm

from pneumatics.hydraulics.circuit import VALVE, HydraulicCircuit
from pneumatics.hydraulics.effects import HydraulicEffects, apply_to_cfg
from pneumatics.hydraulics.hysteresis import Hysteresis
from pneumatics.hydraulics.kernel import pack, pack_ports, step_kernel

RESTART_S = 1.0
SMOOTH_HZ = 10.0
"""Half-amplitude frequency of the smoothing splines of the angle and the torque [Hz]
(:func:`identification.base.smoothing.spline_cutoff_hz`): above the position loop's motion
and the chambers' ~5 Hz corner.  The oil spring (beta D_v / V = 4.5e8 Pa/rad) turns the
angle's noise left below the cut-off into pressure error (0.3 mrad white at 1 kHz leaves
~0.04 mrad, ~19 kPa, in 10 Hz): on a null case the nominal model's held-out J (4 channels,
noise variances) was 12.8 with the discrepancy principle's lighter smoothing, 5.7 at 8 Hz,
5.6 at 15 Hz and 24 at 4 Hz (too much lag)."""
BURN_IN_S = 0.3
SUBSTEP_S = 5.0e-4
"""Largest substep of the replay [s] (two per sample at 1 kHz).  The simulator steps at 0.2 ms;
on a noise-free 10 s recording with a drooping supply and a lost accumulator the replay's
pressure error was 2.30 / 2.72 kPa rms at 0.2 ms, 2.38 / 2.85 kPa at 0.5 ms and 2.56 / 3.14 kPa
at 1 ms (chambers a / b), all far below the transducers' 20 kPa noise; the doctor's time is
replays."""


@dataclass
class Trace:
    """One recording prepared for the doctor: (N,) arrays, SI units."""

    time: np.ndarray
    current_a: np.ndarray       # valve current applied from each sample to the next
    angle: np.ndarray           # measured vane angle [rad]
    p_a: np.ndarray
    p_b: np.ndarray
    torque: np.ndarray | None   # joint torque sensor [N m] (optional)
    smooth: dict                # smoothing-spline angle and derivatives: "q", "qd", "qdd"; "tau", "taud"
    scored: np.ndarray          # (N,) bool: after the burn-in
    restart: np.ndarray         # (N,) bool: chamber pressures restarted from the measurement here
    source: str = ""
    braced: bool = False        # the load locked by the brace (paper 001 Fig. 2a; sidecar "braced")

    def head(self, seconds: float) -> Trace:
        m = self.time - self.time[0] <= seconds
        cut = lambda a: None if a is None else a[m]  # noqa: E731
        return Trace(self.time[m], self.current_a[m], self.angle[m], self.p_a[m], self.p_b[m], cut(self.torque),
                     {k: v[m] for k, v in self.smooth.items()}, self.scored[m], self.restart[m], self.source,
                     self.braced)


def make_trace(time, current_a, angle, p_a, p_b, torque=None, source="", restart_s=RESTART_S,
               braced: bool = False) -> Trace:
    from identification.base.smoothing import smooth_derivatives

    t = np.asarray(time, float)
    rel = t - t[0]
    restart = np.zeros(t.size, bool)
    restart[0] = True
    idx = np.searchsorted(rel, np.arange(restart_s, rel[-1], restart_s))
    restart[idx[idx < t.size]] = True
    lam = (2.0 * math.pi * SMOOTH_HZ) ** -4 / float(np.median(np.diff(t)))  # spline_cutoff_hz inverted
    q, qd, qdd = smooth_derivatives(t, np.asarray(angle, float), order=2, lam=lam)
    smooth = {"q": q, "qd": qd, "qdd": qdd}
    if torque is not None:
        smooth["tau"], smooth["taud"] = smooth_derivatives(t, np.asarray(torque, float), order=1, lam=lam)
    return Trace(t, np.asarray(current_a, float), np.asarray(angle, float), np.asarray(p_a, float),
                 np.asarray(p_b, float), None if torque is None else np.asarray(torque, float), smooth,
                 rel >= BURN_IN_S, restart, source, bool(braced))


def hysteresis_output(cfg_hysteresis, current_a: np.ndarray) -> np.ndarray:
    """(N,) i_hys [A] of the recorded currents, from a demagnetised valve (paper 001 §4)."""
    h = Hysteresis(cfg_hysteresis)
    h.demagnetize()
    return np.array([h(float(i)) for i in current_a])


@functools.lru_cache(maxsize=64)
def tip_matrices(servovalve, saturation_current_a: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(Phi (2, 2), Gamma (2,)): the valve tip's exact zero-order-hold step (eq. 4), as
    :class:`pneumatics.hydraulics.servovalve.ValveTip` computes it."""
    w = 2.0 * math.pi * servovalve.tip_natural_frequency_hz
    z = servovalve.tip_damping_ratio
    aug = np.zeros((3, 3))
    aug[:2, :2] = np.array([[0.0, 1.0], [-w * w, -2.0 * z * w]]) * dt
    aug[:2, 2] = np.array([0.0, w * w * servovalve.tip_travel_m / saturation_current_a]) * dt
    e = expm(aug)
    return np.ascontiguousarray(e[:2, :2]), np.ascontiguousarray(e[:2, 2])


@njit(cache=True)
def _replay(t, i_tip, theta, omega, restart, pa_m, pb_m, y0, x0, prm, modes, tap_p, tap_a, phi, gam, n_sub, out):
    y = y0.copy()
    tap = np.zeros(2)
    x, v = x0, 0.0  # the tip at rest at its static position for the first current
    n = t.size
    for j in range(n):
        if restart[j]:
            y[4] = pa_m[j]
            y[5] = pb_m[j]
        out[j, 0] = y[4]
        out[j, 1] = y[5]
        out[j, 2] = y[0]
        if j + 1 < n:
            h = (t[j + 1] - t[j]) / n_sub
            for k in range(n_sub):
                x, v = phi[0, 0] * x + phi[0, 1] * v + gam[0] * i_tip[j], phi[1, 0] * x + phi[1, 1] * v + gam[1] * i_tip[j]
                s = (k + 1.0) / n_sub
                th = theta[j] + s * (theta[j + 1] - theta[j])
                om = omega[j] + s * (omega[j + 1] - omega[j])
                step_kernel(y, prm, modes, tap_p, tap_a, x, th, om, h, tap)


def vane_speed(tr: Trace, shaft_compliance_rad_per_nm: float | None = None) -> np.ndarray:
    """(N,) the vane's speed [rad/s] the replay is driven by: the smoothed encoder's, or, on a
    braced trace with a torque sensor and a shaft compliance c given, the shaft's twist rate
    c dtau/dt (the load is locked, so the vane moves only by the twist, tau = (theta_v -
    theta_load) / c, sarcos_elbow.xml): the torque's 0.1 N m noise makes it 1e-5 rad, the
    encoder's 0.3 mrad, and the oil spring (4.5e8 Pa/rad) turns the difference into pressure."""
    if tr.braced and tr.torque is not None and shaft_compliance_rad_per_nm is not None:
        return shaft_compliance_rad_per_nm * tr.smooth["taud"]
    return tr.smooth["qd"]


def replay_oil(tr: Trace, cfg, fx: HydraulicEffects, i_hys: np.ndarray | None = None,
               shaft_compliance_rad_per_nm: float | None = None) -> dict:
    """Predicted ``p_a``, ``p_b`` (as the transducers read them, offsets included) and
    ``p_supply`` [Pa] of trace ``tr`` under fluid parameters ``cfg`` and effects ``fx``.
    ``i_hys``: the hysteresis output when already known (it depends on the current and k0 only);
    ``shaft_compliance_rad_per_nm``: the shaft's (nominal + ``fx``'s) for a braced trace
    (:func:`vane_speed`)."""
    cfg = apply_to_cfg(cfg, fx)
    if i_hys is None:
        i_hys = hysteresis_output(cfg.hysteresis, tr.current_a)
    circ = HydraulicCircuit(cfg.oil, cfg.power, cfg.supply_line, cfg.return_line, cfg.servovalve, cfg.vane)
    dt = float(np.median(np.diff(tr.time)))
    n_sub = max(1, math.ceil(dt / SUBSTEP_S - 1e-9))
    phi, gam = tip_matrices(cfg.servovalve, cfg.hysteresis.saturation_current_a, dt / n_sub)
    modes, tap_p, tap_a = pack_ports([VALVE, VALVE])
    out = np.empty((tr.time.size, 3))
    off_a, off_b = fx.pressure_sensor_offset_a_pa, fx.pressure_sensor_offset_b_pa
    theta = tr.smooth["q"] - fx.angle_sensor_offset_rad
    omega = vane_speed(tr, shaft_compliance_rad_per_nm)
    _replay(tr.time, i_hys + fx.null_shift_a, theta, omega, tr.restart, tr.p_a - off_a,
            tr.p_b - off_b, circ.null_state(),
            float(i_hys[0] + fx.null_shift_a) * cfg.servovalve.tip_travel_m / cfg.hysteresis.saturation_current_a, pack(circ), modes, tap_p, tap_a, phi, gam, n_sub, out)
    return {"p_a": out[:, 0] + off_a, "p_b": out[:, 1] + off_b, "p_supply": out[:, 2]}
