"""Physics the nominal SARCOS elbow model may leave out: the hydraulic plant's effect families.

One field per family and place, each a deviation from the nominal model (0 = the nominal
model).  The simulator applies them with :func:`build_sim` (and the sensor offsets with
:func:`add_sensor_offsets`); the hydraulic doctor (identification/doctor/hydraulic) fits the
same fields with the same laws, so a finding's parameters are these fields.

=========================  ====================================================================
family (DESIGN.md name)    law and where it acts (paper 001 unless said)
=========================  ====================================================================
``valve_hysteresis``       wider or narrower Jiles-Atherton loop: k0 + ``hysteresis_extra_k0_a``
                           (eqs. 2-3; k0 sets the coercive current)
``valve_null_shift``       the tip's null is off: x_v = g (i_hys + ``null_shift_a``) (eq. 4 with
                           a bias current; Merritt, *Hydraulic Control Systems* §5.6, null bias)
``valve_leak``             worn valve: extra stage-1 clearance G_s and G_r + ``valve_leak_m3_per_pa_s``
                           (supply -> tip node and tip node -> return, §2.3, eqs. 11-12)
``piston_leak``            cross-vane leakage R_l + ``vane_leak_m3_per_pa_s`` (eqs. 8-9)
``line_dynamics``          a longer (or softer) passage from the valve to chamber a / b: its oil
                           volume V_l1 / V_l2 + ``line_volume_extra_{a,b}_m3`` (Table 1, eqs. 8-9)
``supply_droop``           the pump's pressure falls with the flow drawn:
                           P = P_pump - ``pump_droop_pa_s_per_m3`` Q_s (Merritt §8)
``coulomb_friction``       vane Coulomb friction tau_c + ``coulomb_extra_nm`` (eq. 13)
``viscous_friction``       vane viscous friction b_v + ``viscous_extra_nm_s_per_rad`` (eq. 13)
``shaft_compliance``       a softer shaft: 1/k_s + ``shaft_compliance_extra_rad_per_nm`` (eq. 18,
                           §3.2.2); the strain gauge still reads the true torque
``pressure_sensor_offset`` constant error of the chamber a / b transducer [Pa]
``angle_sensor_offset``    constant error of the vane encoder [rad]
``force_sensor_offset``    constant error of the joint torque sensor [N m]
=========================  ====================================================================
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..errors import ConfigError
from ..recording import Recording

#: recording columns of the elbow (DESIGN.md names): see :mod:`.runner`
ANGLE, P_A, P_B, TORQUE, CURRENT = "q.elbow", "p_a.elbow", "p_b.elbow", "tau.elbow", "i.elbow"


@dataclass(frozen=True)
class HydraulicEffects:
    """Deviations from the nominal elbow, SI units (all 0: the nominal model)."""

    hysteresis_extra_k0_a: float = 0.0
    null_shift_a: float = 0.0
    valve_leak_m3_per_pa_s: float = 0.0
    vane_leak_m3_per_pa_s: float = 0.0
    line_volume_extra_a_m3: float = 0.0
    line_volume_extra_b_m3: float = 0.0
    pump_droop_pa_s_per_m3: float = 0.0
    coulomb_extra_nm: float = 0.0
    viscous_extra_nm_s_per_rad: float = 0.0
    shaft_compliance_extra_rad_per_nm: float = 0.0
    pressure_sensor_offset_a_pa: float = 0.0
    pressure_sensor_offset_b_pa: float = 0.0
    angle_sensor_offset_rad: float = 0.0
    torque_sensor_offset_nm: float = 0.0

    def replace(self, **changes) -> HydraulicEffects:
        return dataclasses.replace(self, **changes)


def _section(cfg, name: str, **changes):
    return dataclasses.replace(cfg, **{name: dataclasses.replace(getattr(cfg, name), **changes)})


def apply_to_cfg(cfg, fx: HydraulicEffects):
    """The ``fluid.toml`` parameters (:class:`~.config.HydraulicCfg`) with the oil-side effects."""
    h, v, s, pw = cfg.hysteresis, cfg.servovalve, cfg.vane, cfg.power
    k0 = h.k0_a + fx.hysteresis_extra_k0_a
    extra_a = s.extra_line_volume_a_m3 + fx.line_volume_extra_a_m3
    extra_b = s.extra_line_volume_b_m3 + fx.line_volume_extra_b_m3
    if k0 <= 0 or min(extra_a, extra_b) < 0:
        raise ConfigError(f"hydraulic effects: k0 {k0:g} A must stay positive and the line volumes "
                          f"{extra_a:g}, {extra_b:g} m^3 added, not taken (hysteresis_extra_k0_a, line_volume_extra_*)")
    cfg = _section(cfg, "hysteresis", k0_a=k0)
    cfg = _section(cfg, "servovalve",
                   supply_clearance_m3_per_pa_s=v.supply_clearance_m3_per_pa_s + fx.valve_leak_m3_per_pa_s,
                   return_clearance_m3_per_pa_s=v.return_clearance_m3_per_pa_s + fx.valve_leak_m3_per_pa_s)
    cfg = _section(cfg, "vane", leak_coefficient_m3_per_pa_s=s.leak_coefficient_m3_per_pa_s + fx.vane_leak_m3_per_pa_s,
                   extra_line_volume_a_m3=extra_a, extra_line_volume_b_m3=extra_b)
    return _section(cfg, "power", pump_droop_pa_s_per_m3=pw.pump_droop_pa_s_per_m3 + fx.pump_droop_pa_s_per_m3)


def apply_to_sim(sim, fx: HydraulicEffects):
    """The mechanical effects and the null shift on a built :class:`~.sim.HydraulicJointSim`
    (MuJoCo's frictionloss, damping and shaft stiffness changed in place); call before reset."""
    m = sim.model
    vane, shaft = sim._vane, m.joint("shaft").id
    m.dof_frictionloss[vane] += fx.coulomb_extra_nm
    m.dof_damping[vane] += fx.viscous_extra_nm_s_per_rad
    compliance = 1.0 / m.jnt_stiffness[shaft] + fx.shaft_compliance_extra_rad_per_nm
    if min(m.dof_frictionloss[vane], m.dof_damping[vane], compliance) < 0:
        raise ConfigError("hydraulic effects: friction, damping and shaft compliance must stay >= 0")
    m.jnt_stiffness[shaft] = 1.0 / compliance
    sim.shaft_stiffness_nm_per_rad = float(m.jnt_stiffness[shaft])  # the gauge reads the true torque
    sim.coulomb_friction_nm = float(m.dof_frictionloss[vane])
    sim.null_shift_a = fx.null_shift_a
    return sim


def build_sim(fx: HydraulicEffects = HydraulicEffects(), cfg=None, name: str = "sarcos_elbow"):
    """A :class:`~.sim.HydraulicJointSim` of shipped model ``name`` (or ``cfg``) with ``fx``."""
    import models

    from .config import load_hydraulic_cfg
    from .sim import HydraulicJointSim

    cfg = load_hydraulic_cfg(models.fluid_path(name)) if cfg is None else cfg
    sim = HydraulicJointSim(apply_to_cfg(cfg, fx), models.mjcf_path(name, scene=True))
    apply_to_sim(sim, fx)
    sim.reset()
    return sim


def add_sensor_offsets(rec: Recording, fx: HydraulicEffects) -> Recording:
    """``rec`` with the sensor offsets added to its measured columns (in place; returned)."""
    for col, off in ((P_A, fx.pressure_sensor_offset_a_pa), (P_B, fx.pressure_sensor_offset_b_pa),
                     (ANGLE, fx.angle_sensor_offset_rad), (TORQUE, fx.torque_sensor_offset_nm)):
        if off and col in rec.columns:
            rec.columns[col] = rec.columns[col] + off
    return rec
