"""The elbow's mechanical side as equation errors, from the measured pressures, angle and torque.

The MJCF (models/sarcos_elbow/sarcos_elbow.xml) has two coordinates on one axis: the vane angle
theta_v (hinge ``elbow``) and the shaft twist s (hinge ``shaft``); the load's angle is
theta_l = theta_v + s.  The joint torque sensor reads tau = -k_s s (pneumatics.hydraulics.sim).
Newton's law for each body about the axis (paper 001 eqs. 13-14, with the shaft's damping b_s
and the load tendon's damping b_l of the MJCF)::

    vane:  J_v theta_v'' = D_v (P_a - P_b) - b_v theta_v' - tau_c sign(theta_v') - tau - b_s tau' / k_s
    load:  J_l theta_l'' = tau + b_s tau' / k_s - b_l theta_l' - W sin(theta_l),
           theta_l = theta_v - tau / k_s, and theta_l'' taken as theta_v'' (see equation_errors)

On a braced trace (the load locked, sidecar ``"braced": true``) the load equation does not hold
(the brace carries the load) and the shaft's law is a channel of its own, ``brace`` [rad]::

    brace:  theta_v - theta_B - tau / k_s = 0,   theta_B the locked load's angle (the trace's mean)

(the encoder's 0.3 mrad noise against a twist of tens of N m / k_s: paper 001 §3.2.2 measures
the shaft's stiffness this way).  Each equation's error (left minus right side, N m) is a
residual channel, with the measured
pressures and torque as they are (their white noise propagates) and the angle's and torque's
derivatives from smoothing splines.  The vane equation is scored only while the vane slides
(|theta_v'| > ``SLIDING_RAD_S``): while it sticks the Coulomb friction is any value in
[-tau_c, tau_c].  Without a torque sensor the two are one rigid-body equation (shaft stiff):
(J_v + J_l) theta'' = D_v P_L - (b_v + b_l) theta' - tau_c sign(theta') - W sin(theta).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pneumatics.hydraulics.effects import HydraulicEffects

SLIDING_RAD_S = 0.05   # vane speed above which its Coulomb friction is tau_c sign(theta_v')
SETTLE_S = 0.02        # ... and for this long after a stick-slip transition (friction still switching)
TRANSITION_S = 0.06    # the pressure channels skip this long either side of a stick-slip transition


@dataclass(frozen=True)
class Mechanics:
    """Nominal mechanical parameters (read from the MJCF by :func:`from_model`)."""

    d_v: float           # vane displacement [m^3/rad]
    j_v: float           # vane inertia about the axis [kg m^2]
    j_l: float           # load inertia about the axis [kg m^2]
    w: float             # load weight moment m g r [N m]
    tau_c: float         # vane Coulomb friction [N m]
    b_v: float           # vane viscous friction [N m s/rad]
    b_l: float           # load damping [N m s/rad]
    k_s: float           # shaft stiffness [N m/rad]
    b_s: float           # shaft damping [N m s/rad]

    def scaled(self, inertia: float, weight: float) -> Mechanics:
        """The load's inertia and weight moment scaled by (1 + ``inertia``), (1 + ``weight``)."""
        from dataclasses import replace

        return replace(self, j_l=self.j_l * (1.0 + inertia), w=self.w * (1.0 + weight))


def from_model(sim, d_v: float) -> Mechanics:
    """The nominal :class:`Mechanics` of a built :class:`~pneumatics.hydraulics.sim.HydraulicJointSim`."""
    import mujoco

    m, d = sim.model, sim.data
    mujoco.mj_forward(m, d)
    vane, load = m.body("vane").id, m.body("load").id
    shaft, elbow = m.joint("shaft").id, m.joint("elbow").id
    axis = 1  # the y axis of sarcos_elbow.xml
    j_v = float(m.body_inertia[vane][axis])
    r = float(np.linalg.norm(m.body_ipos[load][[0, 2]]))
    j_l = float(m.body_inertia[load][axis] + m.body_mass[load] * r ** 2)
    w = float(m.body_mass[load] * -m.opt.gravity[2] * r)
    tendon = m.tendon("load_angle").id
    return Mechanics(d_v=d_v, j_v=j_v, j_l=j_l, w=w, tau_c=float(m.dof_frictionloss[m.jnt_dofadr[elbow]]),
                     b_v=float(m.dof_damping[m.jnt_dofadr[elbow]]), b_l=float(m.tendon_damping[tendon]),
                     k_s=float(m.jnt_stiffness[shaft]), b_s=float(m.dof_damping[m.jnt_dofadr[shaft]]))


def sliding_mask(time: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """(N,) bool: the vane slides, and has for at least SETTLE_S."""
    moving = np.abs(qd) > SLIDING_RAD_S
    dt = float(np.median(np.diff(time)))
    n = max(1, int(round(SETTLE_S / dt)))
    ok = moving.copy()
    for k in range(1, n + 1):  # the previous n samples slid too, in the same direction
        ok[k:] &= moving[:-k] & (np.sign(qd[k:]) == np.sign(qd[:-k]))
        ok[:k] = False
    return ok


def equation_errors(tr, mech: Mechanics, fx: HydraulicEffects) -> dict:
    """Per channel (N,) equation error [N m]: ``vane`` and ``load`` with a torque sensor, else
    ``rigid``; the measured columns corrected by the hypothesised sensor offsets."""
    s = tr.smooth
    q, qd, qdd = s["q"] - fx.angle_sensor_offset_rad, s["qd"], s["qdd"]
    p_l = (tr.p_a - fx.pressure_sensor_offset_a_pa) - (tr.p_b - fx.pressure_sensor_offset_b_pa)
    tau_c = mech.tau_c + fx.coulomb_extra_nm
    b_v = mech.b_v + fx.viscous_extra_nm_s_per_rad
    friction = b_v * qd + tau_c * np.sign(qd)
    hydraulic = mech.d_v * p_l
    if tr.torque is None:
        rigid = hydraulic - (mech.j_v + mech.j_l) * qdd - friction - mech.b_l * qd - mech.w * np.sin(q)
        return {"rigid": rigid}
    out = {}
    compliance = 1.0 / mech.k_s + fx.shaft_compliance_extra_rad_per_nm
    tau = tr.torque - fx.torque_sensor_offset_nm
    tau_s, taud = s["tau"] - fx.torque_sensor_offset_nm, s["taud"]
    transmitted = tau + mech.b_s * taud * compliance
    theta_l = q - tau_s * compliance
    vane = hydraulic - mech.j_v * qdd - friction - transmitted
    # the load's acceleration is the vane's: the twist's own acceleration (compliance x tau'')
    # needs the torque's second derivative, which the spline of a 0.1 N m-noisy torque gives
    # as noise far above the shaft mode's share (~0.03 N m); leaving it in bent the load's
    # inertia to its -30 % bound on clean simulated recordings
    load = transmitted - mech.j_l * qdd - mech.b_l * (qd - taud * compliance) - mech.w * np.sin(theta_l)
    out.update(vane=vane, load=load)
    if tr.braced:
        twist = tr.angle - fx.angle_sensor_offset_rad - tau * compliance
        out["brace"] = twist - np.mean(twist[tr.scored])
    return out


def near_transition(time: np.ndarray, qd: np.ndarray, window_s: float = TRANSITION_S) -> np.ndarray:
    """(N,) bool: within ``window_s`` of a stick-slip transition (|theta_v'| crossing
    SLIDING_RAD_S).  There the vane starts or stops within a few ms, faster than a smoothing
    spline of the noisy angle can follow, and the oil spring (beta D_v / V = 4.5e8 Pa/rad) turns
    the spline's lag into pressure errors far above the transducers' noise."""
    moving = np.abs(qd) > SLIDING_RAD_S
    edges = time[np.flatnonzero(np.diff(moving.astype(np.int8)) != 0) + 1]
    if edges.size == 0:
        return np.zeros(time.size, bool)
    k = np.clip(np.searchsorted(edges, time), 1, edges.size - 1) if edges.size > 1 else np.zeros(time.size, int)
    nearest = np.minimum(np.abs(time - edges[k]), np.abs(time - edges[np.maximum(k - 1, 0)]))
    return nearest < window_s


def channel_masks(tr, channels) -> dict:
    """channel -> (N,) bool of the samples it is scored on: the vane and rigid equations only
    while sliding, the pressures and the load equation away from stick-slip transitions (where
    the spline's acceleration of the vane lags the jump); on a braced trace the brace channel
    everywhere and the load and rigid equations nowhere (the brace carries the load); on a
    free trace the brace channel nowhere."""
    slide = sliding_mask(tr.time, tr.smooth["qd"])
    calm = ~near_transition(tr.time, tr.smooth["qd"])
    out = {}
    for c in channels:
        if c == "brace":
            out[c] = tr.scored & tr.braced
        elif tr.braced and c in ("load", "rigid"):
            out[c] = np.zeros(tr.time.size, bool)
        else:
            out[c] = tr.scored & (slide if c in ("vane", "rigid") else calm)
    return out
