"""Model-predictive control of the chamber pressures by iterative LQG (paper 002 §IV-B.4).

Given a reference pressure-difference trajectory d*(t + k Delta), k = 1..n, from a
higher-level controller (the model-based PIDF, eqs. 16-17), find the valve commands that
make the air dynamics produce it, "taking into account a few time steps into the future"
(the valves act mostly a couple of steps later).  The redundancy (only the differences
p^+ - p^- are specified, not both pressures) is resolved by a quadratic control cost
centred at each valve's null (5 V), with box constraints 0-10 V::

    J = sum_{k=1..n} w_d |d(p_k) - d*_k|^2 / bar^2  +  sum_{k=0..n-1} w_u |u_k - u_null|^2 / V^2
    p_{k+1} = F(p_k, u_k; V(t), dV/dt)                     (the fluid layer's eqs. 6-9)

F is the simulator's own chamber model (:func:`pneumatics.chamber.integrate`, adaptive ROS2
over the control step, valve map :func:`pneumatics.valve.valve_areas`, orifice flow
:func:`pneumatics.medium.orifice_flow`), with the volumes from the joint motion predicted
over the horizon.  Each chamber's pressure depends only on its own command, so the
Jacobians dF/dp, dF/du are diagonal and come from one batched finite-difference call.

The optimiser is iterative LQR/LQG (Todorov & Li 2005; box constraints as in Tassa, Mansard
& Todorov 2014, "Control-limited differential dynamic programming": a bounded QP per step
in the backward pass, feedback gains zeroed on clamped commands), warm-started from the
previous control step's solution shifted by one step.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pneumatics.config import spec
from pneumatics.errors import ConfigError
from pneumatics.valve import valve_areas

from .pid import BAR, COMMAND_MAX_V, COMMAND_MIN_V


@dataclass(frozen=True, kw_only=True)
class ILQGCfg:
    """Horizon, costs and iterations of the pressure MPC."""

    horizon: int = spec(3, "prediction steps n (paper: 2)", "-", 1, 20)
    step_s: float = spec(0.01, "prediction step Delta (the control period)", "s", 1e-3, 0.1)
    weight_d: float = spec(1.0, "cost on the pressure-difference error, per bar^2", "1/bar^2", 0.0, 1e6)
    weight_u: float = spec(0.02, "cost on valve commands away from null, per V^2", "1/V^2", 1e-6, 1e3)
    iterations: int = spec(4, "iLQG iterations per control step", "-", 1, 50)
    fd_step_pa: float = spec(50.0, "finite-difference step in pressure", "Pa", 1e-3, 1e4)
    fd_step_v: float = spec(0.25, "half-width of the central difference in command; wider than the "
                            "valve's deadband (0.15 V), where dF/du = 0 would stall the optimiser", "V", 1e-3, 2.0)

    def __post_init__(self):
        if self.horizon < 1 or self.iterations < 1 or self.step_s <= 0:
            raise ConfigError("ILQGCfg: horizon and iterations must be >= 1 and step_s > 0")


class AirModel:
    """The fluid layer's chamber dynamics over one prediction step, batched over copies.

    Uses the simulator's own compiled chamber update (:func:`pneumatics.kernel.integrate_chambers`:
    eq. 9 with the orifice flows of eqs. 6-8, adaptive ROS2) with the step set to the
    prediction step, on ``copies`` stacked copies of the arm's chambers (for the finite
    differences), and the valve map :func:`pneumatics.valve.valve_areas`.
    """

    def __init__(self, robot, step_s: float, copies: int = 4):
        import mujoco

        from pneumatics.kernel import pack

        self.tables = tab = robot.tables
        m = robot.model
        n_act = robot.actuator_ids.size
        self.gear = np.empty(n_act)
        self.joint_col = np.empty(n_act, int)
        for k, i in enumerate(robot.actuator_ids):
            if int(m.actuator_trntype[i]) != int(mujoco.mjtTrn.mjTRN_JOINT):
                raise ConfigError(f"{robot.name}: the pressure MPC needs joint transmissions (constant moment "
                                  f"arm); actuator {robot.actuator_names[k]!r} has another kind")
            self.gear[k] = m.actuator_gear[i, 0]
            self.joint_col[k] = robot.joint_names.index(m.joint(m.actuator_trnid[i, 0]).name)
        self.step_s = step_s
        self.copies = copies
        act, ch, glob = pack(tab, np.arange(n_act), step_s)
        # copies: actuator rows repeated, each copy's chambers pointing at its own actuators
        self._act = np.ascontiguousarray(np.tile(act, (copies, 1)))
        self._act[:, 4] = np.arange(copies * n_act)
        self._ch = np.ascontiguousarray(np.tile(ch, (copies, 1)))
        self._ch[:, 3] += np.repeat(np.arange(copies) * n_act, ch.shape[0])
        self._glob = glob
        self._rows = np.tile(tab.valve, (copies, 1))
        self.n_act, self.n_ch = n_act, ch.shape[0]

    def lengths(self, q: np.ndarray) -> np.ndarray:
        """(n_act,) actuator lengths at joint positions q (n_joint,)."""
        return self.gear * q[self.joint_col]

    def step(self, p: np.ndarray, u: np.ndarray, length0: np.ndarray, length1: np.ndarray) -> np.ndarray:
        """Pressures after one step; p and u are (c, n_ch), c <= copies, sharing the motion
        from actuator lengths ``length0`` to ``length1`` (n_act,)."""
        from pneumatics.kernel import integrate_chambers

        c = p.shape[0]
        nc, na = c * self.n_ch, c * self.n_act
        a_s, a_e = valve_areas(np.clip(u, COMMAND_MIN_V, COMMAND_MAX_V).reshape(-1), self._rows[:nc])
        out = np.ascontiguousarray(p, float).reshape(-1).copy()
        areas = np.ascontiguousarray(np.column_stack([a_s, a_e]))
        integrate_chambers(out, areas, np.tile(length0, c), np.tile(length1, c), self._act[:na],
                           self._ch[:nc], self._glob.copy())
        return out.reshape(c, self.n_ch)


def box_qp(h: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_iter: int = 20):
    """min 1/2 x'Hx + g'x subject to lo <= x <= hi, H positive definite (n small).

    Active-set iteration: solve on the free set with the clamped variables at their bounds,
    clamp free variables that leave the box, release clamped ones whose gradient points
    inwards, until the KKT conditions hold.  Returns (x, free mask)."""
    n = g.size
    clamped_lo = np.zeros(n, bool)
    clamped_hi = np.zeros(n, bool)
    x = np.clip(np.zeros(n), lo, hi)
    for _ in range(max_iter):
        free = ~(clamped_lo | clamped_hi)
        x = np.where(clamped_lo, lo, np.where(clamped_hi, hi, 0.0))
        if free.any():
            f = np.where(free)[0]
            x[f] = np.linalg.solve(h[np.ix_(f, f)], -(g[f] + h[np.ix_(f, ~free)] @ x[~free]))
        below, above = free & (x < lo - 1e-12), free & (x > hi + 1e-12)
        if below.any() or above.any():
            clamped_lo |= below
            clamped_hi |= above
            continue
        grad = h @ x + g
        release = (clamped_lo & (grad < 0)) | (clamped_hi & (grad > 0))
        if not release.any():
            return x, free
        clamped_lo &= ~release
        clamped_hi &= ~release
    return np.clip(x, lo, hi), ~(clamped_lo | clamped_hi)


@dataclass
class PressureMPC:
    """iLQG over the air dynamics; ``solve(p0, q_pred, d_ref) -> u0`` (n_ch,) volts."""

    cfg: ILQGCfg
    air: AirModel
    null_v: np.ndarray
    _u: np.ndarray = field(default=None, init=False)
    last_cost: float = field(default=float("nan"), init=False)
    last_prediction: np.ndarray = field(default=None, init=False)

    def reset(self):
        self._u = None

    def _cost(self, ps, us, d_ref):
        c = self.cfg
        d = (ps[1:, 0::2] - ps[1:, 1::2]) / BAR
        return float(c.weight_d * np.sum((d - d_ref / BAR) ** 2) + c.weight_u * np.sum((us - self.null_v) ** 2))

    def _rollout(self, p0, us, lengths):
        ps = np.empty((us.shape[0] + 1, p0.size))
        ps[0] = p0
        for k in range(us.shape[0]):
            ps[k + 1] = self.air.step(ps[k][None], us[k][None], lengths[k], lengths[k + 1])[0]
        return ps

    def solve(self, p0: np.ndarray, q_pred: np.ndarray, d_ref: np.ndarray) -> np.ndarray:
        """Commands for now.

        Args:
          p0: (n_ch,) measured pressures [Pa].
          q_pred: (n + 1, n_joint) predicted joint positions at t, t + Delta, ..., t + n Delta.
          d_ref: (n, n_act) reference pressure differences [Pa] at t + Delta .. t + n Delta.
        """
        c = self.cfg
        n, n_ch = c.horizon, p0.size
        lengths = np.array([self.air.lengths(q) for q in q_pred])
        if self._u is None:
            us = np.tile(self.null_v, (n, 1))
        else:
            us = np.vstack([self._u[1:], self._u[-1:]])
        ps = self._rollout(p0, us, lengths)
        cost = self._cost(ps, us, d_ref)
        wd, wu = c.weight_d / BAR ** 2, c.weight_u
        # cost Hessian in p for one actuator: d = p_a - p_b
        sel = np.zeros((n_ch // 2, n_ch))
        sel[np.arange(n_ch // 2), 2 * np.arange(n_ch // 2)] = 1.0
        sel[np.arange(n_ch // 2), 2 * np.arange(n_ch // 2) + 1] = -1.0
        lxx = 2 * wd * sel.T @ sel
        eye = np.eye(n_ch)
        mu = 0.0
        for _ in range(c.iterations):
            # diagonal Jacobians by one batched finite difference per step
            a_diag = np.empty((n, n_ch))
            b_diag = np.empty((n, n_ch))
            for k in range(n):
                pp = np.vstack([ps[k], ps[k] + c.fd_step_pa, ps[k], ps[k]])
                uu = np.vstack([us[k], us[k], us[k] + c.fd_step_v, us[k] - c.fd_step_v])
                out = self.air.step(pp, uu, lengths[k], lengths[k + 1])
                a_diag[k] = (out[1] - out[0]) / c.fd_step_pa
                b_diag[k] = (out[2] - out[3]) / (2 * c.fd_step_v)
            # backward pass
            d_err = ps[n, 0::2] - ps[n, 1::2] - d_ref[n - 1]
            vx = 2 * wd * sel.T @ d_err
            vxx = lxx.copy()
            kff = np.zeros((n, n_ch))
            kfb = np.zeros((n, n_ch, n_ch))
            for k in range(n - 1, -1, -1):
                a, b = a_diag[k], b_diag[k]
                qx = a * vx
                qu = 2 * wu * (us[k] - self.null_v) + b * vx
                qxx = a[:, None] * vxx * a[None, :]
                quu = b[:, None] * vxx * b[None, :] + (2 * wu + mu) * eye
                qux = b[:, None] * vxx * a[None, :]
                du, free = box_qp(quu, qu, COMMAND_MIN_V - us[k], COMMAND_MAX_V - us[k])
                kk = np.zeros((n_ch, n_ch))
                if free.any():
                    f = np.where(free)[0]
                    kk[np.ix_(f, np.arange(n_ch))] = -np.linalg.solve(quu[np.ix_(f, f)], qux[f])
                kff[k], kfb[k] = du, kk
                vx = qx + kk.T @ quu @ du + kk.T @ qu + qux.T @ du
                vxx = qxx + kk.T @ quu @ kk + kk.T @ qux + qux.T @ kk
                vxx = 0.5 * (vxx + vxx.T)
                if k > 0:  # running cost on the state p_k
                    d_err = ps[k, 0::2] - ps[k, 1::2] - d_ref[k - 1]
                    vx = vx + 2 * wd * sel.T @ d_err
                    vxx = vxx + lxx
            # forward pass with a backtracking line search
            improved = False
            for alpha in (1.0, 0.5, 0.25, 0.1):
                un = np.empty_like(us)
                pn = np.empty_like(ps)
                pn[0] = p0
                for k in range(n):
                    un[k] = np.clip(us[k] + alpha * kff[k] + kfb[k] @ (pn[k] - ps[k]), COMMAND_MIN_V, COMMAND_MAX_V)
                    pn[k + 1] = self.air.step(pn[k][None], un[k][None], lengths[k], lengths[k + 1])[0]
                new_cost = self._cost(pn, un, d_ref)
                if new_cost < cost:
                    improved = True
                    us, ps, cost = un, pn, new_cost
                    break
            if not improved:
                break
        self._u = us
        self.last_cost = cost
        self.last_prediction = ps
        return us[0].copy()


@dataclass
class MPCModelBased:
    """Model-based PIDF whose pressure loop is the iLQG MPC (paper 002 §IV-B.4 with §V-C).

    The high-level law gives the desired pressure difference dbar = e / k_F + d^ (eq. 16) at
    t + k Delta (e held, d^ from the reference ahead); the MPC turns it into valve commands.
    The joints are predicted to move as the reference does over the horizon:
    q(t + k Delta) = q(t) + q*(t + k Delta) - q*(t).
    """

    outer: object          # controllers.model_based.ModelBasedPIDF
    mpc: PressureMPC

    def reset(self):
        self.outer.reset()
        self.mpc.reset()

    def reference(self, t):
        return self.outer.reference(t)

    def __call__(self, t, obs):
        c = self.mpc.cfg
        e = self.outer.effort(t, obs)
        e_pa = e / self.outer.kf(e.size) * BAR
        times = t + c.step_s * np.arange(c.horizon + 1)
        d_ref = np.array([e_pa + self.outer.feedforward_pa(tk) for tk in times[1:]])
        r0 = self.outer.reference(t)
        q_pred = np.array([obs.q + self.outer.reference(tk) - r0 for tk in times])
        return self.mpc.solve(np.asarray(obs.p, float), q_pred, d_ref)


def build_mpc_model_based(robot, reference, model, pidf_cfg, cfg: ILQGCfg | None = None, lead_s: float = 0.0):
    """The MPC variant of the model-based controller for ``robot``."""
    from .model_based import ModelBasedCfg

    cfg = cfg or ILQGCfg()
    null = robot.tables.valve[:, 0]
    outer = ModelBasedCfg(pidf=pidf_cfg, lead_s=lead_s).build(reference, null, model)
    return MPCModelBased(outer, PressureMPC(cfg, AirModel(robot, cfg.step_s), np.asarray(null, float)))
