"""The hydraulic circuit of the SARCOS joint: six states, their ODE and an L-stable step.

State ``y`` (6,): ``[P_s, Q_s, P_r, Q_r, P_a, P_b]`` — supply pressure at the valve [Pa],
supply-line flow [m^3/s], return pressure at the valve [Pa], return-line flow [m^3/s] and the
two chamber pressures [Pa] (all absolute).  Right-hand side (paper 001 eqs. 6-10; the
chamber law is dp/dt = beta/V (Q - dV/dt) for oil of bulk modulus beta)::

    dP_s/dt = (Q_s - Q_valve,in) / C_s                       dQ_s/dt = (P_pump - P_s - R_s Q_s) / I_s
    dP_r/dt = (Q_valve,out - Q_r) / C_r                      dQ_r/dt = (P_r - P_tank - R_r Q_r) / I_r
    dP_a/dt = beta/V_a (Q_a - D_v omega - R_l (P_a - P_b))   dP_b/dt = beta/V_b (Q_b + D_v omega + R_l (P_a - P_b))

with Q_a, Q_b the flows into the chambers through the valve's metering orifices (eq. 5) and
its clearance leakage (see :mod:`.servovalve`).  A port may instead be ``blocked`` or
connected to a ``tap`` — a fixed pressure behind an orifice, as the manifold of paper 001
§3.1 does for the leakage measurement ("by strategically blocking certain ports, a flow rate,
such as actuator leakage, may be measured by volume measurements over time").

Integration: linearly-implicit (Rosenbrock) Euler with the analytic Jacobian J = df/dy,
``y+ = y + dt (I - dt J)^-1 f(y)``.  It is L-stable, so the stiff parts (a chamber fed by a
nearly closed orifice has time constants of microseconds; the return line's oil is a tiny
capacitance) are damped, not amplified, at any step.  The vane angle and velocity are held
over the step (they come from MuJoCo).  It preserves the linear invariant of the circuit
exactly: sum over nodes of C dP equals dt (Q_s - Q_r) at the end of the step (with C = V/beta
for the chambers), i.e. oil volume is conserved to round-off (see tests/test_sarcos.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..oil import OilCfg, orifice_flow_scalar
from .kernel import pack, pack_ports, step_kernel
from .lines import LineCfg, PowerCfg
from ..oil import CAVITATION_FLOOR_PA
from .servovalve import ServovalveCfg, metering_areas
from .vane import VaneCfg

STATE_NAMES = ("p_supply", "q_supply", "p_return", "q_return", "p_a", "p_b")
#: the states held at the oil's cavitation floor: the chambers, and the supply and return lines'
#: ends (fast current reversals at the saturation current drew the return line's end to
#: -79 kPa absolute in a soak of random currents)
FLOORED_STATES = (0, 2, 4, 5)  # p_supply, p_return, p_a, p_b


@dataclass(frozen=True)
class Port:
    """How a chamber port is connected: ``valve`` (normal), ``blocked``, or ``tap`` (a fixed
    pressure ``pressure_pa`` behind an orifice of ``area_m2``, e.g. a graduated cylinder at
    tank pressure or the supply through the manifold)."""

    mode: str = "valve"
    pressure_pa: float = 0.0
    area_m2: float = 0.0

    def __post_init__(self):
        if self.mode not in ("valve", "blocked", "tap"):
            raise ConfigError(f"port mode {self.mode!r}: expected valve, blocked or tap")
        if self.mode == "tap" and (self.pressure_pa <= 0.0 or self.area_m2 <= 0.0):
            raise ConfigError("a tap needs pressure_pa > 0 (absolute) and area_m2 > 0")


VALVE, BLOCKED = Port("valve"), Port("blocked")


class HydraulicCircuit:
    """Supply line, servovalve, vane chambers and return line of one joint."""

    def __init__(self, oil: OilCfg, power: PowerCfg, supply_line: LineCfg, return_line: LineCfg,
                 valve: ServovalveCfg, vane: VaneCfg, kernel: str = "fast"):
        if kernel not in ("fast", "reference"):
            raise ConfigError(f"unknown kernel {kernel!r}; valid: fast, reference")
        self.kernel = kernel
        self.oil, self.power, self.valve, self.vane = oil, power, valve, vane
        self.r_s, self.i_s, self.c_s = supply_line.elements(oil)
        self.r_s += power.pump_droop_pa_s_per_m3  # the pump's droop: a source resistance in series
        self.r_r, self.i_r, self.c_r = return_line.elements(oil)
        self.g_sp, self.g_pr, self.g_sr = valve.leak_conductances()
        self.k = oil.orifice_coefficient
        self.dp_t2 = oil.laminar_dp_pa ** 2
        self._packed = pack(self)
        self.ports = [VALVE, VALVE]
        self.y = self.null_state()
        self.tap_volume_m3 = np.zeros(2)  # oil delivered from chamber a/b into its tap
        self._inputs = (0.0, 0.0, 0.0)

    @property
    def ports(self) -> list[Port]:
        """How chamber ports a and b are connected (see :class:`Port`)."""
        return self._ports

    @ports.setter
    def ports(self, ports):
        self._ports = list(ports)
        self._packed_ports = pack_ports(self._ports)

    def null_state(self) -> np.ndarray:
        """Steady state at null with the pump's pressure and the null leakage flowing."""
        q = self.valve.null_leakage_m3_s(self.power.pump_pa, self.power.tank_pa)
        p_s = self.power.pump_pa - self.r_s * q
        p_r = self.power.tank_pa + self.r_r * q
        gs, gr = self.valve.supply_clearance_m3_per_pa_s, self.valve.return_clearance_m3_per_pa_s
        p_mid = (gs * p_s + gr * p_r) / (gs + gr) if gs + gr > 0 else 0.5 * (p_s + p_r)
        return np.array([p_s, q, p_r, q, p_mid, p_mid])

    def rates(self, y, x_v: float, theta: float, omega: float, jacobian: bool = True):
        """``(f, J, flows)``: dy/dt (6,), df/dy (6, 6) and the named flows [m^3/s]."""
        p_s, q_s, p_r, q_r, p_a, p_b = (float(v) for v in y)
        k, t2 = self.k, self.dp_t2
        a_sa, a_ar, a_sb, a_br = metering_areas(x_v, self.valve)
        q_sa, d_sa = orifice_flow_scalar(k * a_sa, p_s - p_a, t2)
        q_ar, d_ar = orifice_flow_scalar(k * a_ar, p_a - p_r, t2)
        q_sb, d_sb = orifice_flow_scalar(k * a_sb, p_s - p_b, t2)
        q_br, d_br = orifice_flow_scalar(k * a_br, p_b - p_r, t2)
        g_sp, g_pr, g_sr = self.g_sp, self.g_pr, self.g_sr
        J = np.zeros((6, 6)) if jacobian else None
        # valve flows into each chamber and their derivatives wrt (P_s, P_r, P_own)
        chambers = []
        for q_in, d_in, q_out, d_out, p in ((q_sa, d_sa, q_ar, d_ar, p_a), (q_sb, d_sb, q_br, d_br, p_b)):
            q_valve = q_in - q_out + g_sp * (p_s - p) - g_pr * (p - p_r)
            chambers.append([q_valve, d_in + g_sp, d_out + g_pr, -d_in - d_out - g_sp - g_pr])
        # supply draw and return flow of the valve (ports on taps or blocked draw nothing)
        q_sup = 2.0 * g_sr * (p_s - p_r)
        q_ret = 2.0 * g_sr * (p_s - p_r)
        dsup = {0: 2.0 * g_sr, 2: -2.0 * g_sr}
        dret = {0: 2.0 * g_sr, 2: -2.0 * g_sr}
        tap_flows = [0.0, 0.0]
        for j, (q_in, d_in, q_out, d_out, p) in enumerate(
                ((q_sa, d_sa, q_ar, d_ar, p_a), (q_sb, d_sb, q_br, d_br, p_b))):
            port, col = self.ports[j], 4 + j
            if port.mode == "valve":
                q_sup += q_in + g_sp * (p_s - p)
                dsup[0] += d_in + g_sp
                dsup[col] = dsup.get(col, 0.0) - d_in - g_sp
                q_ret += q_out + g_pr * (p - p_r)
                dret[col] = dret.get(col, 0.0) + d_out + g_pr
                dret[2] += -d_out - g_pr
            elif port.mode == "blocked":
                chambers[j] = [0.0, 0.0, 0.0, 0.0]
            else:  # tap: flow from the tap's fixed pressure into the chamber
                q_tap, d_tap = orifice_flow_scalar(k * port.area_m2, port.pressure_pa - p, t2)
                chambers[j] = [q_tap, 0.0, 0.0, -d_tap]
                tap_flows[j] = -q_tap
        v_a, v_b = self.vane.volumes(theta)
        beta, d_v, r_l = self.oil.bulk_modulus_pa, self.vane.displacement_m3_per_rad, \
            self.vane.leak_coefficient_m3_per_pa_s
        q_leak = r_l * (p_a - p_b)
        q_vane = d_v * omega
        f = np.array([
            (q_s - q_sup) / self.c_s,
            (self.power.pump_pa - p_s - self.r_s * q_s) / self.i_s,
            (q_ret - q_r) / self.c_r,
            (p_r - self.power.tank_pa - self.r_r * q_r) / self.i_r,
            beta / v_a * (chambers[0][0] - q_vane - q_leak),
            beta / v_b * (chambers[1][0] + q_vane + q_leak),
        ])
        if jacobian:
            J[0, 1] = 1.0 / self.c_s
            for col, d in dsup.items():
                J[0, col] -= d / self.c_s
            J[1, 0], J[1, 1] = -1.0 / self.i_s, -self.r_s / self.i_s
            for col, d in dret.items():
                J[2, col] += d / self.c_r
            J[2, 3] = -1.0 / self.c_r
            J[3, 2], J[3, 3] = 1.0 / self.i_r, -self.r_r / self.i_r
            for row, vol, sign in ((4, v_a, 1.0), (5, v_b, -1.0)):
                _, d_ps, d_pr, d_own = chambers[row - 4]
                c = beta / vol
                J[row, 0] += c * d_ps
                J[row, 2] += c * d_pr
                J[row, row] += c * d_own
                J[row, 4] += -sign * c * r_l
                J[row, 5] += sign * c * r_l
        flows = {"supply_line": q_s, "return_line": q_r, "valve_in": q_sup, "valve_out": q_ret,
                 "to_a": chambers[0][0], "to_b": chambers[1][0], "leak_ab": q_leak,
                 "tap_a": tap_flows[0], "tap_b": tap_flows[1]}
        return f, J, flows

    def step(self, dt: float, x_v: float, theta: float, omega: float) -> np.ndarray:
        """Advance the state by ``dt`` [s] (linearly-implicit Euler); returns the new state."""
        self._inputs = (x_v, theta, omega)
        if self.kernel == "fast":
            step_kernel(self.y, self._packed, *self._packed_ports, x_v, theta, omega, dt,
                        self.tap_volume_m3)
            return self.y
        f, J, _ = self.rates(self.y, x_v, theta, omega)
        dy = np.linalg.solve(np.eye(6) - dt * J, dt * f)
        self.y = self.y + dy
        if self.ports[0].mode == "tap" or self.ports[1].mode == "tap":
            # flows at the end of the step: the quadrature that makes the update conserve volume
            flows = self.flows()
            self.tap_volume_m3 += dt * np.array([flows["tap_a"], flows["tap_b"]])
        floored = list(FLOORED_STATES)
        self.y[floored] = np.maximum(self.y[floored], CAVITATION_FLOOR_PA)
        return self.y

    def flows(self) -> dict[str, float]:
        """Named flows [m^3/s] at the current state and the last step's valve tip and vane motion."""
        return self.rates(self.y, *self._inputs, jacobian=False)[2]

    def stored_volume_m3(self, theta: float) -> float:
        """sum C_i P_i over the pressure nodes [m^3] (compressed oil, linear in the state)."""
        v_a, v_b = self.vane.volumes(theta)
        b = self.oil.bulk_modulus_pa
        return self.c_s * self.y[0] + self.c_r * self.y[2] + (v_a * self.y[4] + v_b * self.y[5]) / b
