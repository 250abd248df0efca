"""Compiled fast path of the fluid update: the same equations as :mod:`pneumatics.chamber`
(the readable numpy reference), scalar loops compiled with numba, writing the cylinder forces
into MuJoCo's ``data.ctrl`` in place.  A numpy call costs ~20 us whatever the array size,
more than a 2-DOF ``mj_step``; this kernel costs ~1 us.  ``tests/test_kernel.py`` checks it
against the reference to round-off.

Table layouts (from :meth:`pneumatics.tables.FluidTables.packed`):
  act  (n_act, 7): area_a, area_b, stroke, length_zero, MuJoCo actuator id (= ctrl index),
                   piston (a -> b) leak area [m^2] (effect piston_leak, 0 = none),
                   its laminar form's conductance [kg/(s Pa)] (0 = none)
  ch   (n_ch, 16): area, dead volume, is_a, actuator index, 8 valve columns,
                   leak area to the room [m^2] (effect external_leak, 0 = none),
                   its laminar form's conductance [kg/(s Pa)] (0 = none), the valve's
                   supply-land and exhaust-land clearance conductances [kg/(s Pa)] at the
                   spool's present position (valve_leak, clearance form; written by the
                   command path, 0 = none)
  fric (n_f, 7):   dof address, Coulomb [N m], extra breakaway [N m], Stribeck velocity
                   [rad/s], viscous [N m s/rad], velocity-power coefficient [N m (s/rad)^n] and
                   exponent n (effects coulomb_friction, stiction, viscous_friction)
  glob (22 + flow_polynomial.SIZE,): R, k, T, n, laminar ratio, r_c, c_choke, c_sub, supply,
                   room, dt, slope of the linearised flow near r = 1, supply droop
                   [Pa/(kg/s)] (effect supply_droop, 0 = none), supply pressure in effect
                   (state), the droop's time constant [s] (reservoir form, 0 = none), the
                   compressor_cycling form's receiver volume [m^3] (0 = none), delivery
                   [kg/s], band [Pa], cut-out [Pa], leak [kg/(s Pa)] and whether it runs
                   (state, 0 / 1); from POLY = 21 on, the flow function's polynomial
                   (pneumatics.flow_polynomial); last (QUADRATIC_DROOP), the supply droop per
                   (kg/s)^2 [Pa/(kg/s)^2] (regulator_orifice form, 0 = none)
"""
from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from .flow_polynomial import DEGREE, SIZE, flow_polynomial
from .medium import flow_function

GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
MAX_HALVINGS = 6
MAX_REL_CHANGE = 0.25
ERR_TOL = 1e-3
#: where the flow function's polynomial starts in glob (module docstring)
POLY = 21
#: glob's last slot: the quadratic supply droop (after the polynomial, so the slots before it keep their places)
QUADRATIC_DROOP = POLY + SIZE
#: glob's compressor_cycling entries (module docstring)
RECEIVER, RUNNING = 15, 20


@numba.njit(cache=True, error_model="numpy", inline="always")
def _flow_g(r, glob):
    """(g, dg/dr) of g(r) = psi(r)^2 at r_c <= r <= laminar_ratio: the polynomial of
    :mod:`pneumatics.flow_polynomial` packed at glob[POLY:], by Horner's rule."""
    t = (r - glob[POLY]) * glob[POLY + 1]
    g = glob[POLY + 2 + DEGREE]
    d = 0.0
    for j in range(DEGREE - 1, -1, -1):
        d = d * t + g
        g = g * t + glob[POLY + 2 + j]
    return g, d * glob[POLY + 1]


@numba.njit(cache=True, error_model="numpy", inline="always")
def _unit_flow(p_up, p_down, glob):
    """(flow, d/d p_up, d/d p_down) per unit area for p_up >= p_down (medium.unit_flow).

    Straight-line code with conditional expressions (no min/max, no calls into libm but
    sqrt): LLVM turns a loop of it over the chambers into vector instructions.
    """
    rl, rc, c_choke, c_sub = glob[4], glob[5], glob[6], glob[7]
    r = p_down / p_up
    r_in = rc if r < rc else (rl if r > rl else r)  # the polynomial's interval
    g, dg = _flow_g(r_in, glob)
    psi = math.sqrt(g)  # g >= g(laminar_ratio) > 0 on the interval
    dpsi = dg / (2.0 * psi)
    slope = glob[11]
    choked, subsonic = r <= rc, r <= rl
    flow = c_choke * p_up if choked else (c_sub * p_up * psi if subsonic else slope * (p_up - p_down))
    d_up = c_choke if choked else (c_sub * (psi - r * dpsi) if subsonic else slope)
    d_down = 0.0 if choked else (c_sub * dpsi if subsonic else -slope)
    return flow, d_up, d_down


@numba.njit(cache=True, error_model="numpy", inline="always")
def orifice_flow_compiled(area, p_from, p_to, glob):
    """Signed mass flow [kg/s] and its derivatives (medium.orifice_flow)."""
    forward = p_from >= p_to
    f, d_hi, d_lo = _unit_flow(p_from if forward else p_to, p_to if forward else p_from, glob)
    return ((area * f, area * d_hi, area * d_lo) if forward else
            (-area * f, -area * d_lo, -area * d_hi))


@numba.njit(cache=True, error_model="numpy", inline="always")
def _rate(p, volume, volume_rate, a_s, a_e, glob, m_extra):
    rt = glob[0] * glob[2]
    n = glob[3]
    m_s, _, dms = orifice_flow_compiled(a_s, glob[13], p, glob)  # supply pressure in effect (supply_droop)
    m_e, dme, _ = orifice_flow_compiled(a_e, p, glob[9], glob)
    return (n / volume * (rt * (m_s - m_e + m_extra) - p * volume_rate),
            n / volume * (rt * (dms - dme) - volume_rate))


@numba.njit(cache=True, error_model="numpy", inline="always")
def write_forces(p, ctrl, act, glob):
    """ctrl[actuator] = A_a p_a - A_b p_b - (A_a - A_b) p_room for every actuator."""
    room = glob[9]
    for j in range(act.shape[0]):
        aa, ab = act[j, 0], act[j, 1]
        ctrl[int(act[j, 4])] = aa * p[2 * j] - ab * p[2 * j + 1] - (aa - ab) * room


@numba.njit(cache=True, error_model="numpy", inline="always")
def integrate_chambers(p, areas, prev_length, length, act, ch, glob):
    """Advance p in place over one step, the actuators moving from prev_length to length.

    Args (shapes): p (n_ch,) Pa; areas (n_ch, 2) valve supply and exhaust areas [m^2]
    (pneumatics.valve.valve_areas of the commands); prev_length (n_act,) lengths of the
    fluid actuators at the step's start; length (nu,) MuJoCo's ``data.actuator_length`` at
    its end, indexed by each actuator's MuJoCo id (act[:, 4]); act, ch, glob as in the
    module docstring.
    """
    integrate_chambers_into(p, areas, prev_length, length, act, ch, glob, work_array(ch.shape[0]))


#: rows of the integration's scratch array (WORK_ROWS, n_ch): leak flows [kg/s], mid-step
#: volume [m^3], its rate [m^3/s], supply and exhaust valve areas [m^2], the whole step's new
#: pressure [Pa] and whether it was accepted (1/0)
EXTRA, VOLUME, VOLUME_RATE, AREA_S, AREA_E, WHOLE, ACCEPTED = range(7)
WORK_ROWS = 7


@numba.njit(cache=True)
def work_array(n_chambers):
    """Scratch for :func:`integrate_chambers_into`, allocated once per physics loop."""
    return np.empty((WORK_ROWS, n_chambers))


# The chamber integration and its ROS2 steps are plain calls, not numba's inline="always": the
# IR-level inlining copied the whole adaptive integrator into every physics loop that calls it
# (physics_steps, period_steps, period_start, the compiled closed loop), and a first run in a
# fresh install spent 190 s compiling them; as calls LLVM still decides what to inline, the
# first compile takes about 10 s and the steps ran no slower (pneumasim bench, 2026-11-26).
@numba.njit(cache=True, error_model="numpy")
def integrate_chambers_into(p, areas, prev_length, length, act, ch, glob, work):
    """:func:`integrate_chambers` with ``work`` (WORK_ROWS, n_ch) a scratch array
    (:func:`work_array`): the physics loop allocates it once per call, not once per step."""
    dt = glob[10]
    n_ch = ch.shape[0]
    m_extra = work[EXTRA]
    _leak_flows(p, act, ch, glob, m_extra)
    volume, volume_rate, a_s, a_e = work[VOLUME], work[VOLUME_RATE], work[AREA_S], work[AREA_E]
    for i in range(n_ch):  # gathers from the actuator table, kept out of the vector loop
        volume[i], volume_rate[i] = _chamber_volume(i, prev_length, length, act, ch, dt)
        a_s[i], a_e[i] = areas[i, 0], areas[i, 1]
    whole, accepted = work[WHOLE], work[ACCEPTED]
    _whole_steps(p, volume, volume_rate, a_s, a_e, m_extra, glob, whole, accepted)
    for i in range(n_ch):  # a chamber whose whole step failed restarts with halved steps
        p[i] = whole[i] if accepted[i] > 0.0 else _adaptive_ros2(p[i], volume[i], volume_rate[i], a_s[i], a_e[i],
                                                                 glob, dt, m_extra[i], 1)
    if glob[RECEIVER] > 0.0:  # supply_droop, compressor_cycling: the receiver's air balance
        _receiver_step(p, areas, glob)
    elif glob[12] > 0.0 or glob[QUADRATIC_DROOP] > 0.0:  # supply_droop: the supply falls with its total flow
        total = 0.0
        for i in range(n_ch):
            m_s, _, _ = orifice_flow_compiled(areas[i, 0], glob[8], p[i], glob)
            total += max(m_s, 0.0)
        k, k2 = glob[12], glob[QUADRATIC_DROOP]
        drop = glob[8] - glob[13]  # the flow the droop in effect follows (effects.supply_droop.flow_of_droop)
        before = drop / k if k2 <= 0.0 else 2.0 * drop / (k + math.sqrt(k * k + 4.0 * k2 * drop)) if drop > 0.0 else 0.0
        m_f = before + (total - before) * dt / (glob[14] + dt)
        glob[13] = glob[8] - (k * m_f + k2 * m_f * m_f)


@numba.njit(cache=True, error_model="numpy")
def _receiver_step(p, areas, glob):
    """effects.supply_droop.receiver_step, compiled: the receiver (its pressure glob[13] is the
    supply's) one step on, the valves drawing their flows at chamber pressures p."""
    total = 0.0
    for i in range(p.shape[0]):
        m_s, _, _ = orifice_flow_compiled(areas[i, 0], glob[13], p[i], glob)
        total += max(m_s, 0.0)
    pr = glob[13]
    if pr >= glob[RECEIVER + 3]:
        glob[RUNNING] = 0.0
    elif pr <= glob[RECEIVER + 3] - glob[RECEIVER + 2]:
        glob[RUNNING] = 1.0
    m_in = glob[RECEIVER + 1] * glob[RUNNING] - total - glob[RECEIVER + 4] * (pr - glob[9])
    glob[13] = pr + glob[10] * glob[0] * glob[2] / glob[RECEIVER] * m_in


@numba.njit(cache=True, error_model="numpy", inline="always")
def clearance_flow_compiled(p, g_supply, g_exhaust, supply_pa, room_pa):
    """effects.valve_leak.clearance_flows for one chamber at pressure p: the net flow in [kg/s]
    through its valve's lands of conductances g_supply, g_exhaust (the simulator's and the
    doctor's compiled steps)."""
    return (g_supply * (supply_pa - p) * (supply_pa + p) - g_exhaust * (p - room_pa) * (p + room_pa)) / (2.0 * room_pa)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _leak_flows(p, act, ch, glob, m_extra):
    """m_extra[i] = the leak flows into chamber i [kg/s], explicit over the step (their time
    constants >> dt): to the room (external_leak), across the piston (piston_leak) and through
    the valve's clearance from the supply in effect and to the room (valve_leak, clearance)."""
    m_extra[:] = 0.0
    for i in range(ch.shape[0]):
        if ch[i, 12] > 0.0:
            m_x, _, _ = orifice_flow_compiled(ch[i, 12], p[i], glob[9], glob)
            m_extra[i] -= m_x
        if ch[i, 13] > 0.0:  # laminar: G (p^2 - p_room^2) / (2 p_room) (effects.external_leak)
            m_extra[i] -= ch[i, 13] * (p[i] - glob[9]) * (p[i] + glob[9]) / (2.0 * glob[9])
        if ch[i, 14] > 0.0 or ch[i, 15] > 0.0:  # a valve's clearance
            m_extra[i] += clearance_flow_compiled(p[i], ch[i, 14], ch[i, 15], glob[13], glob[9])
    for j in range(act.shape[0]):
        if act[j, 5] > 0.0:
            m_ab, _, _ = orifice_flow_compiled(act[j, 5], p[2 * j], p[2 * j + 1], glob)
            m_extra[2 * j] -= m_ab
            m_extra[2 * j + 1] += m_ab
        if act[j, 6] > 0.0:
            m_ab = act[j, 6] * (p[2 * j] - p[2 * j + 1]) * (p[2 * j] + p[2 * j + 1]) / (2.0 * glob[9])
            m_extra[2 * j] -= m_ab
            m_extra[2 * j + 1] += m_ab


# fastmath "contract" only: fused multiply-adds, no reassociation and no assumption that
# values are finite (the acceptance test checks for NaN and inf).
@numba.njit(cache=True, error_model="numpy", fastmath={"contract"})
def _whole_steps(p, volume, volume_rate, a_s, a_e, m_extra, glob, whole, accepted):
    """The first try of :func:`_adaptive_ros2`, one ROS2 step over dt, for every chamber at
    once: contiguous arrays in and out and straight-line code, so LLVM vectorises the loop
    (several chambers per instruction)."""
    dt = glob[10]
    for i in range(p.shape[0]):
        q, ok = _ros2_whole_step(p[i], volume[i], volume_rate[i], a_s[i], a_e[i], glob, dt, m_extra[i])
        whole[i] = q
        accepted[i] = 1.0 if ok else 0.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def write_friction(qvel, qfrc_applied, fric):
    """qfrc_applied[dof] = friction torque at qvel (:func:`friction_at`)."""
    for k in range(fric.shape[0]):
        dof = int(fric[k, 0])
        qfrc_applied[dof] = friction_at(qvel[dof], fric[k, 1], fric[k, 2], fric[k, 3], fric[k, 4], fric[k, 5],
                                        fric[k, 6])


@numba.njit(cache=True, error_model="numpy", inline="always")
def friction_at(v, coulomb, stiction_extra, stribeck, viscous, power_viscous, exponent):
    """The friction torque [N m] at joint velocity v [rad/s] (pneumatics.effects.friction.friction_torque,
    its reference; the power term continued linearly below 0.01 rad/s as there)."""
    s = math.tanh(v / 0.01)
    power = v * max(abs(v), 0.01) ** (exponent - 1.0)
    return -(coulomb * s + stiction_extra * math.exp(-(v / stribeck) ** 2) * s + viscous * v + power_viscous * power)


@numba.njit(cache=True, error_model="numpy")
def fluid_step_fast(p, areas, prev_length, length, ctrl, act, ch, glob):
    """Integrate the step that just ended (prev_length -> length), write the forces of the new
    pressures into ``ctrl`` and remember ``length`` in ``prev_length``."""
    fluid_step_into(p, areas, prev_length, length, ctrl, act, ch, glob, work_array(ch.shape[0]))


@numba.njit(cache=True, error_model="numpy", inline="always")
def fluid_step_into(p, areas, prev_length, length, ctrl, act, ch, glob, work):
    """:func:`fluid_step_fast` with a scratch array (:func:`work_array`)."""
    integrate_chambers_into(p, areas, prev_length, length, act, ch, glob, work)
    write_forces(p, ctrl, act, glob)
    for j in range(act.shape[0]):
        prev_length[j] = length[int(act[j, 4])]


@numba.njit(cache=True, error_model="numpy", inline="always")
def _chamber_volume(i, prev_length, length, act, ch, dt):
    """(volume [m^3] at mid-step, its rate [m^3/s]) of chamber i (chamber.chamber_geometry)."""
    j = int(ch[i, 3])
    stroke = act[j, 2]
    x0 = min(max(prev_length[j] - act[j, 3], 0.0), stroke)
    x1 = min(max(length[int(act[j, 4])] - act[j, 3], 0.0), stroke)
    x_mid = 0.5 * (x0 + x1)
    if ch[i, 2] > 0.5:
        return ch[i, 1] + ch[i, 0] * x_mid, ch[i, 0] * (x1 - x0) / dt
    return ch[i, 1] + ch[i, 0] * (stroke - x_mid), -ch[i, 0] * (x1 - x0) / dt


@numba.njit(cache=True, error_model="numpy", inline="always")
def _ros2_whole_step(p0, volume, vrate, a_s, a_e, glob, dt, m_extra):
    """(pressure, accepted) of one ROS2 step over dt from p0: the first try of _adaptive_ros2
    and each of its substeps.  Rejected: non-finite, too large a change, or the embedded
    first-order solution p0 + dt k1 disagreeing by more than ERR_TOL (step-doubling control,
    Hairer-Wanner IV.7)."""
    f0, jac = _rate(p0, volume, vrate, a_s, a_e, glob, m_extra)
    denom = 1.0 - GAMMA * dt * jac
    k1 = f0 / denom
    f1, _j = _rate(p0 + dt * k1, volume, vrate, a_s, a_e, glob, m_extra)
    k2 = (f1 - 2.0 * k1) / denom
    q_new = p0 + 1.5 * dt * k1 + 0.5 * dt * k2
    ok = (math.isfinite(q_new) & (abs(q_new - p0) <= MAX_REL_CHANGE * p0)
          & (0.5 * dt * abs(k1 + k2) <= ERR_TOL * p0))  # & not `and`: no branches in the vector loop
    return q_new, ok


@numba.njit(cache=True, error_model="numpy")
def _adaptive_ros2(p0, volume, vrate, a_s, a_e, glob, dt, m_extra, first_level):
    """One step dt of the adaptive ROS2 of chamber.integrate, for one chamber, trying 2^level
    substeps from ``first_level`` on (1 after a failed whole step, 0 otherwise)."""
    q = p0
    for level in range(first_level, MAX_HALVINGS + 1):
        n_sub = 2 ** level
        h = dt / n_sub
        q = p0
        ok = True
        for _ in range(n_sub):
            q, accepted = _ros2_whole_step(q, volume, vrate, a_s, a_e, glob, h, m_extra)
            ok = ok and accepted
        if ok:
            break
    return q


@numba.njit(cache=True, error_model="numpy")
def static_transient_fast(p0, volume, a_s, a_e, glob, dt, out):
    """Fixed-volume transients (chamber.static_transient): fills out (T, n) from p0 (n,)."""
    n = p0.shape[0]
    for i in range(n):
        out[0, i] = p0[i]
    for k in range(out.shape[0] - 1):
        for i in range(n):
            out[k + 1, i] = _adaptive_ros2(out[k, i], volume[i], 0.0, a_s[i], a_e[i], glob, dt, 0.0, 0)


def pack(tables, ctrl_index, dt):
    """Kernel tables (act, ch, glob) from :class:`FluidTables`, ctrl indices and the step."""
    act, ch, glob = tables.packed()
    act = np.ascontiguousarray(np.column_stack([act, np.asarray(ctrl_index, float), tables.piston_leak_m2,
                                                tables.piston_leak_g]))
    clearance = np.zeros((ch.shape[0], 2))  # the command path writes a valve's clearance here
    ch = np.ascontiguousarray(np.column_stack([ch, tables.external_leak_m2, tables.external_leak_g, clearance]))
    return act, ch, pack_glob(tables.gas, tables.supply_pa, tables.room_pa, dt, tables.supply_droop_pa_per_kg_s,
                              tables.supply_droop_tau_s, tables.supply_compressor, tables.supply_droop_pa_per_kg2_s2)


def pack_glob(gas, supply_pa: float, room_pa: float, dt: float, droop: float, droop_tau_s: float = 0.0,
              compressor=None, droop_pa_per_kg2_s2: float = 0.0) -> np.ndarray:
    """The kernel's gas and plant constants, ``glob`` of the module docstring; ``compressor``
    (5,) the compressor_cycling form's values (effects.supply_droop.COMPRESSOR_FIELDS) or None.
    Its receiver starts at the cut-out pressure, the compressor off."""
    slope = gas.c_sub * flow_function(gas.laminar_ratio, gas.heat_capacity_ratio) / (1.0 - gas.laminar_ratio)
    receiver = np.zeros(5) if compressor is None else np.asarray(compressor, float)
    start = supply_pa if compressor is None else receiver[3]
    return np.concatenate([gas.as_array(), [supply_pa, room_pa, dt, slope, droop, start, droop_tau_s], receiver, [0.0],
                           flow_polynomial(gas.heat_capacity_ratio, gas.critical_ratio, gas.laminar_ratio),
                           [droop_pa_per_kg2_s2]])


# -- the whole physics loop, compiled -------------------------------------------------------
# mj_step1 / mj_step2 are called straight from compiled code, so n steps run without returning
# to Python (a Python-level loop costs ~1 us a step, a third of a 2-DOF mj_step).  The MuJoCo
# functions' addresses are an argument (MUJOCO_FUNCTIONS), called through a pointer
# (call_mujoco), not constants baked into the machine code: the loop and every compiled caller
# (controllers.compiled_loop) are cached on disk like the rest of the kernel.  Where MuJoCo's
# shared library cannot be found, Simulation falls back to a Python loop around the kernel.
MUJOCO_FUNCTION_NAMES = ("mj_step1", "mj_step2", "mj_kinematics", "mj_comPos", "mj_tendon", "mj_transmission")
STEP1, STEP2, KINEMATICS, COM_POS, TENDON, TRANSMISSION = range(6)


def _mujoco_function_addresses():
    """(6,) uint64 addresses of MUJOCO_FUNCTION_NAMES in this process's libmujoco, or None."""
    import ctypes
    import glob as _glob
    import os

    import mujoco

    libs = sorted(_glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*")))
    if not libs:
        return None
    lib = ctypes.CDLL(libs[0])
    return np.array([ctypes.cast(getattr(lib, name), ctypes.c_void_p).value for name in MUJOCO_FUNCTION_NAMES],
                    np.uint64)


#: addresses of MUJOCO_FUNCTION_NAMES (None where libmujoco.so is not found)
MUJOCO_FUNCTIONS = _mujoco_function_addresses()


@intrinsic
def call_mujoco(typingctx, function_address, model_address, data_address):
    """Call ``void f(const mjModel*, mjData*)`` at ``function_address`` (all three uint64)."""
    sig = types.void(types.uint64, types.uint64, types.uint64)

    def codegen(context, builder, signature, args):
        address, m, d = args
        fnty = ir.FunctionType(ir.VoidType(), [ir.IntType(64), ir.IntType(64)])
        builder.call(builder.inttoptr(address, fnty.as_pointer()), [m, d])
        return context.get_dummy_value()

    return sig, codegen


@numba.njit(cache=True, error_model="numpy")
def physics_steps(n, fns, model_addr, data_addr, p, areas, prev_length, length, ctrl, act, ch,
                  glob, qpos, qvel, acc, qfrc_applied, fric):
    """n physics steps without leaving compiled code (see Simulation.step for the scheme).

    ``fns``: MUJOCO_FUNCTIONS; ``model_addr`` / ``data_addr``: ``MjModel._address`` and
    ``MjData._address`` (uint64).  Adds p (n_ch,), qpos (nq,) and qvel (nv,) at each of the n
    new instants into ``acc`` (n_ch+nq+nv,), for sensor averaging over a control period
    (paper 002 §II).
    """
    period_steps(n, False, True, fns, model_addr, data_addr, p, areas, prev_length, length, ctrl, act, ch,
                 glob, qpos, qvel, acc, qfrc_applied, fric)


@numba.njit(cache=True, error_model="numpy")
def period_steps(n, step1_done, catch_up, fns, model_addr, data_addr, p, areas, prev_length, length, ctrl,
                 act, ch, glob, qpos, qvel, acc, qfrc_applied, fric):
    """:func:`physics_steps`, for a loop that stays compiled from one control period to the next.

    ``step1_done``: the first step's mj_step1 and the fluid update before it were done by
    :func:`period_start`.  ``catch_up`` False leaves the last step's pressures to the next
    period's :func:`period_start` instead of computing the kinematics twice (once here, once in
    the next mj_step1: about a third of an mj_step); p, q, qd are then synchronous only after it.
    """
    work = work_array(p.size)
    for k in range(n):
        if not (k == 0 and step1_done):
            call_mujoco(fns[STEP1], model_addr, data_addr)
        _between_mj_steps(k, p, areas, prev_length, length, ctrl, act, ch, glob, qpos, qvel, acc,
                          qfrc_applied, fric, work)
        call_mujoco(fns[STEP2], model_addr, data_addr)
    if catch_up:  # actuator lengths at the new state, then the last step's pressures
        call_mujoco(fns[KINEMATICS], model_addr, data_addr)
        call_mujoco(fns[COM_POS], model_addr, data_addr)
        call_mujoco(fns[TENDON], model_addr, data_addr)
        call_mujoco(fns[TRANSMISSION], model_addr, data_addr)
        _catch_up(p, areas, prev_length, length, ctrl, act, ch, glob, qpos, qvel, acc, work)


@numba.njit(cache=True, error_model="numpy")
def period_start(fns, model_addr, data_addr, p, areas, prev_length, length, ctrl, act, ch, glob, qpos, qvel,
                 acc, qfrc_applied, fric):
    """After ``period_steps(..., catch_up=False)``: the next step's mj_step1 (which computes the
    actuator lengths the catch-up would), then the last step's pressures, forces and sensor sums,
    exactly as the catch-up makes them.  Follow with ``period_steps(..., step1_done=True, ...)``."""
    call_mujoco(fns[STEP1], model_addr, data_addr)
    _catch_up(p, areas, prev_length, length, ctrl, act, ch, glob, qpos, qvel, acc, work_array(p.size))


@numba.njit(cache=True, error_model="numpy")
def _between_mj_steps(k, p, areas, prev_length, length, ctrl, act, ch, glob, qpos, qvel, acc, qfrc_applied, fric,
                      work):
    """Between mj_step1 and mj_step2 of step k: integrate the fluid over the step that ended
    (none before the first), accumulate the sensors, write forces and friction."""
    if k > 0:
        integrate_chambers_into(p, areas, prev_length, length, act, ch, glob, work)
        for j in range(act.shape[0]):
            prev_length[j] = length[int(act[j, 4])]
        _accumulate(acc, p, qpos, qvel)
    write_forces(p, ctrl, act, glob)
    write_friction(qvel, qfrc_applied, fric)


@numba.njit(cache=True, error_model="numpy")
def _catch_up(p, areas, prev_length, length, ctrl, act, ch, glob, qpos, qvel, acc, work):
    """After the last step's kinematics: its fluid step, forces, and sensor accumulation."""
    fluid_step_into(p, areas, prev_length, length, ctrl, act, ch, glob, work)
    _accumulate(acc, p, qpos, qvel)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _accumulate(acc, p, qpos, qvel):
    n_ch = p.shape[0]
    nq = qpos.shape[0]
    for i in range(n_ch):
        acc[i] += p[i]
    for i in range(nq):
        acc[n_ch + i] += qpos[i]
    for i in range(qvel.shape[0]):
        acc[n_ch + nq + i] += qvel[i]
