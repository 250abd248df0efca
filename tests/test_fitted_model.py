"""The fitted model as files: model.toml (read, write, load_robot(fitted=...)), the mapping of
each reported effect onto the simulator's EffectSet, fitted.xml for plain MuJoCo, the
scenarios' --fitted, and a doctor run's model.toml reproducing its held-out numbers."""
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from identification.doctor.valve_arm.data import prepare, split
from identification.doctor.valve_arm.fitted_model import heldout_replay, replay_mods
from identification.doctor.valve_arm.hypotheses import mechanical_hypotheses, pneumatic_hypotheses
from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods
from identification.doctor.valve_arm.replay import MechMods, coupled_replay
from pneumatics.effects.from_finding import FORMS, FittedModelWarning, effect_set, form_of
from pneumatics.errors import ConfigError, PneumasimError, UnknownNameError
from pneumatics.fitted_mjcf import write_fitted_mjcf
from pneumatics.fitted_model import FittedEffect, FittedModel, fitted_text, read_fitted, write_fitted
from pneumatics.recording import read_csv
from pneumatics.robot import load_robot

BLIND = Path(__file__).resolve().parents[2] / "shared" / "samples" / "arm2-blind"
needs_samples = pytest.mark.skipif(not BLIND.is_dir(), reason="shared/samples not beside the repo")


def est(v, se=0.0):
    return {"value": v, "stderr": se}


def effect(family, form, where, **params):
    return FittedEffect(family, form, where, {k: est(v, 0.1 * abs(v)) for k, v in params.items()})


#: one effect of every (family, form) the arm doctor reports, at distinct places, and where
#: its value must land: (EffectSet attribute, key, expected value or dict)
CASES = [
    (effect("valve_leak", "symmetric", {"actuator": "elbow", "chamber": "a"}, leak_area_m2=2e-8),
     "valve_leak_m2", "elbow.a", 2e-8),
    (effect("valve_leak", "asymmetric", {"actuator": "elbow", "chamber": "b"},
            supply_leak_area_m2=3e-8, exhaust_leak_area_m2=1e-8), "valve_leak_exhaust_m2", "elbow.b", 1e-8),
    (effect("valve_leak", "underlap", {"actuator": "shoulder", "chamber": "b"}, underlap_area_m2=2e-8),
     "valve_underlap", "shoulder.b", {"area_m2": 2e-8, "width_v": 0.6}),
    (effect("valve_leak", "clearance", {"actuator": "shoulder", "chamber": "a"}, clearance_conductance_kg_s_pa=2e-11),
     "valve_clearance", "shoulder.a", {"conductance_kg_s_pa": 2e-11, "width_v": 0.6}),
    (effect("external_leak", "orifice", {"actuator": "shoulder", "chamber": "a"}, leak_area_m2=5e-9),
     "external_leak_m2", "shoulder.a", 5e-9),
    (effect("piston_leak", "orifice", {"actuator": "shoulder"}, leak_area_m2=9e-9), "piston_leak_m2", "shoulder", 9e-9),
    (effect("piston_leak", "laminar", {"actuator": "elbow"}, conductance_kg_s_pa=2e-11),
     "piston_leak_laminar_kg_s_pa", "elbow", 2e-11),
    (effect("valve_hysteresis", "play", {"actuator": "shoulder", "chamber": "b"}, half_width_v=0.3),
     "valve_hysteresis_v", "shoulder.b", 0.3),
    (effect("valve_lag", "first_order", {"actuator": "elbow", "chamber": "a"}, time_constant_s=0.02),
     "valve_lag_s", "elbow.a", 0.02),
    (effect("valve_lag", "slew_limit", {"actuator": "shoulder", "chamber": "a"}, full_stroke_time_s=0.1),
     "valve_slew_s", "shoulder.a", 0.1),
    # the valve's dead time runs on the line's delay (pneumatics.effects.valve_lag)
    (effect("valve_lag", "dead_time", {"actuator": "elbow", "chamber": "b"}, dead_time_s=0.012),
     "line_dynamics", "elbow.b", {"delay_s": 0.012}),
    (effect("line_dynamics", "delay_volume", {"actuator": "shoulder", "chamber": "b"}, delay_s=0.01,
            volume_m3=2e-6), "line_dynamics", "shoulder.b", {"delay_s": 0.01, "volume_m3": 2e-6}),
    (effect("heat_transfer", "newton", {"actuator": "elbow", "chamber": "b"}, conductance_w_k=0.2),
     "heat_transfer", "elbow.b", {"conductance_w_k": 0.2}),
    (effect("pressure_sensor_offset", "additive", {"actuator": "shoulder", "chamber": "a"}, offset_pa=3000.0),
     "pressure_offset_pa", "shoulder.a", 3000.0),
    (effect("pressure_sensor_offset", "warm_up_drift", {"actuator": "elbow", "chamber": "b"}, offset_pa=1000.0,
            drift_pa=-6000.0, time_constant_s=25.0),
     "pressure_drift", "elbow.b", {"drift_pa": -6000.0, "time_constant_s": 25.0}),
    # the torque balance's offset names the actuator; the doctor carries it on chamber a
    (effect("pressure_sensor_offset", "additive", {"actuator": "elbow"}, offset_pa=-2000.0, offset_pa_if_chamber_b=2500.0),
     "pressure_offset_pa", "elbow.a", -2000.0),
    (effect("angle_sensor_offset", "additive", {"joint": "elbow"}, offset_rad=0.03), "angle_offset_rad", "elbow", 0.03),
    (effect("supply_droop", "linear", {"supply": "all"}, droop_pa_per_kg_s=2e7), "supply_droop_pa_per_kg_s", None, 2e7),
    (effect("supply_droop", "regulator_orifice", {"supply": "all"}, droop_pa_per_kg2_s2=1e11, time_constant_s=0.05),
     "supply_droop_pa_per_kg2_s2", None, 1e11),
    (effect("backlash", "dead_zone", {"joint": "elbow"}, gap_rad=0.02), "backlash", "elbow", {"gap_rad": 0.02}),
    (effect("coulomb_friction", "coulomb", {"joint": "shoulder"}, coulomb_nm=0.04), "friction", "shoulder",
     {"coulomb_nm": 0.04}),
    (effect("stiction", "stribeck", {"joint": "elbow"}, coulomb_nm=0.02, breakaway_extra_nm=0.01,
            stribeck_rad_s=0.1), "friction", "elbow",
     {"coulomb_nm": 0.02, "stiction_extra_nm": 0.01, "stribeck_rad_s": 0.1}),
    (effect("viscous_friction", "linear", {"joint": "shoulder"}, viscous_nm_s_per_rad=0.01), "friction", "shoulder",
     {"viscous_nm_s": 0.01}),
    (effect("viscous_friction", "velocity_power", {"joint": "elbow"}, power_coefficient_nm=0.05, exponent=0.5),
     "friction", "elbow", {"power_viscous_nm": 0.05, "viscous_exponent": 0.5}),
]


@pytest.mark.parametrize("e, attr, key, expected", CASES, ids=[f"{c[0].family}-{c[0].form}-{c[0].place}" for c in CASES])
def test_each_reported_effect_lands_in_its_effect_set_entry(arm2, e, attr, key, expected):
    effects, notes = effect_set([e], arm2)
    assert notes == []
    got = getattr(effects, attr) if key is None else getattr(effects, attr)[key]
    assert got == (pytest.approx(expected) if not isinstance(expected, dict) else expected)
    if e.family == "valve_leak" and e.form == "asymmetric":
        assert effects.valve_leak_m2["elbow.b"] == 3e-8


def test_friction_forms_at_one_joint_add_up(arm2):
    effects, _ = effect_set([effect("coulomb_friction", "coulomb", {"joint": "elbow"}, coulomb_nm=0.03),
                             effect("viscous_friction", "linear", {"joint": "elbow"}, viscous_nm_s_per_rad=0.01),
                             effect("stiction", "stribeck", {"joint": "elbow"}, coulomb_nm=0.01,
                                    breakaway_extra_nm=0.02)], arm2)
    assert effects.friction["elbow"] == pytest.approx({"coulomb_nm": 0.04, "viscous_nm_s": 0.01,
                                                       "stiction_extra_nm": 0.02, "stribeck_rad_s": 0.1})


def test_a_power_law_friction_replays_as_the_simulator_runs_it(arm2):
    """The doctor's replays (MechMods.torque) and the simulator (its friction table, the kernel's
    law) apply one fitted velocity-power friction alike, the exponent included."""
    from pneumatics.effects.friction import friction_torque

    fm = FittedModel("arm2", effects=[effect("viscous_friction", "velocity_power", {"joint": "elbow"},
                                             power_coefficient_nm=0.05, exponent=0.5)])
    robot = load_robot("arm2", fitted=fm)
    _, mm = replay_mods(robot)
    qd = np.column_stack([np.zeros(7), np.array([-2.0, -0.3, -0.005, 0.0, 0.004, 0.2, 1.5])])
    (row,) = robot.effects.friction_table(robot)
    np.testing.assert_allclose(mm.torque(np.zeros_like(qd), qd)[:, 1], friction_torque(qd[:, 1], *row[1:]), rtol=1e-12)
    assert mm.torque(np.zeros_like(qd), qd)[5, 1] == pytest.approx(-0.05 * 0.2 ** 0.5)


def test_every_doctor_hypothesis_has_a_form_the_simulator_maps(arm2):
    # mechanical_hypotheses without data leaves out the end stops (they need data to place them)
    for h in pneumatic_hypotheses(arm2) + mechanical_hypotheses(arm2):
        names = [p[0] for p in h.params] + list(h.fixed) + (["volume_m3"] if h.adds_volume else [])
        form = form_of(h.family, names)
        assert set(FORMS[(h.family, form)][0]) <= set(names)
    assert form_of("end_stop", ["stiffness_nm_per_rad", "damping_nm_s_per_rad", "stop_rad", "side_sign"]) == "spring_damper"


@pytest.mark.parametrize("e, attr, key, expected", [c for c in CASES if c[1] not in ("friction", "angle_offset_rad")],
                         ids=[f"{c[0].family}-{c[0].form}-{c[0].place}" for c in CASES
                              if c[1] not in ("friction", "angle_offset_rad")])
def test_the_simulator_and_the_doctors_replay_get_the_same_pneumatic_value(arm2, e, attr, key, expected):
    """The EffectSet the simulator runs and the PneumaticMods the doctor's replays run, both
    built from one fitted entry, hold the same number at the same chamber or actuator."""
    fm = FittedModel("arm2", effects=[e])
    robot = load_robot("arm2", fitted=fm)
    pm, _ = replay_mods(robot)
    eff = robot.effects
    chambers = [f"{a}.{c}" for a, c in arm2.chamber_names]
    pairs = {"valve_leak_m2": lambda: (eff.chamber_array(arm2, "valve_leak_m2"), pm.valve_leak_m2),
             "valve_leak_exhaust_m2": lambda: (eff.chamber_array(arm2, "valve_leak_exhaust_m2"), pm.valve_leak_exhaust_m2),
             "external_leak_m2": lambda: (eff.chamber_array(arm2, "external_leak_m2"), pm.external_leak_m2),
             "piston_leak_m2": lambda: (eff.actuator_array(arm2, "piston_leak_m2"), pm.piston_leak_m2),
             "piston_leak_laminar_kg_s_pa": lambda: (eff.actuator_array(arm2, "piston_leak_laminar_kg_s_pa"),
                                                     pm.piston_leak_g),
             "valve_hysteresis_v": lambda: (eff.chamber_array(arm2, "valve_hysteresis_v"), pm.hysteresis_v),
             "valve_lag_s": lambda: (eff.chamber_array(arm2, "valve_lag_s"), pm.lag_s),
             "valve_underlap": lambda: (np.concatenate(eff.underlap_arrays(arm2)),
                                        np.concatenate([pm.valve_underlap_m2, pm.valve_underlap_width_v])),
             "valve_clearance": lambda: (np.concatenate(eff.clearance_arrays(arm2)),
                                         np.concatenate([pm.valve_clearance_g, pm.valve_clearance_width_v])),
             "valve_slew_s": lambda: (eff.chamber_array(arm2, "valve_slew_s"), pm.stroke_time_s),
             "line_dynamics": lambda: (np.concatenate(eff.line_arrays(arm2)),
                                       np.concatenate([pm.delay_s, np.zeros(len(chambers)) if pm.extra_volume_m3 is None
                                                       else pm.extra_volume_m3])),
             "heat_transfer": lambda: (eff.heat_arrays(arm2)[1][chambers.index(key)], pm.heat_w_k[chambers.index(key)]),
             "pressure_offset_pa": lambda: (eff.chamber_array(arm2, "pressure_offset_pa"), pm.sensor_offset_pa),
             "pressure_drift": lambda: (np.concatenate([eff.chamber_array(arm2, "pressure_offset_pa"),
                                                        *eff.drift_arrays(arm2)]),
                                        np.concatenate([pm.sensor_offset_pa, pm.sensor_drift_pa, pm.sensor_drift_tau_s])),
             "supply_droop_pa_per_kg_s": lambda: (eff.supply_droop_pa_per_kg_s, pm.supply_droop_pa_per_kg_s),
             "supply_droop_pa_per_kg2_s2": lambda: ([eff.supply_droop_pa_per_kg2_s2, eff.supply_droop_tau_s],
                                                    [pm.supply_droop_pa_per_kg2_s2, pm.supply_droop_tau_s]),
             "backlash": lambda: ([eff.backlash["elbow"]["gap_rad"]], [pm.backlash_rad[1]])}
    sim_value, replay_value = pairs[attr]()
    np.testing.assert_allclose(np.asarray(sim_value, float), np.asarray(replay_value, float), rtol=1e-12)
    assert np.any(np.asarray(sim_value) != 0)


def test_the_mechanical_effects_reach_the_doctors_replay(arm2):
    fm = FittedModel("arm2", effects=[c[0] for c in CASES if c[1] in ("friction", "angle_offset_rad")])
    _, mm = replay_mods(load_robot("arm2", fitted=fm))
    np.testing.assert_allclose(mm.coulomb_nm, [0.04, 0.02])
    np.testing.assert_allclose(mm.stiction_extra_nm, [0.0, 0.01])
    np.testing.assert_allclose(mm.viscous_nm_s, [0.01, 0.0])
    np.testing.assert_allclose(mm.angle_offset_rad, [0.0, 0.03])


def full_model() -> FittedModel:
    return FittedModel(
        "arm2", calibration={"supply_area_scale.elbow.a": est(1.2, 0.01), "exhaust_area_scale.shoulder.b": est(0.9, 0.02),
                             "dead_volume_scale.elbow.b": est(1.3, 0.05), "mass_scale.forearm": est(1.1, 0.003),
                             "damping_scale.shoulder": est(1.25, 0.02), "armature_scale.elbow": est(1.5, float("nan"))},
        effects=[c[0] for c in CASES if c[1] != "friction"]
        + [effect("coulomb_friction", "coulomb", {"joint": "shoulder"}, coulomb_nm=0.04),
           effect("viscous_friction", "linear", {"joint": "elbow"}, viscous_nm_s_per_rad=0.01)],
        unexplained=[{"where": {"joint": "elbow"}, "regime": "high velocity", "share_of_residual": 0.3,
                      "evidence": "a \"smooth\" torque removes 30 %"}],
        fitted_on=["run1.csv", "run 2.csv"], heldout_on=["held.csv"], heldout_nrmse_after={"q.elbow": 0.01},
        pneumasim_version="0.1.0")


def test_model_toml_round_trip_is_byte_for_byte(tmp_path):
    path = write_fitted(full_model(), tmp_path / "model.toml")
    text = path.read_text()
    assert text.startswith("# pneumasim fitted model: arm2")
    back = read_fitted(path)
    assert fitted_text(back) == text
    assert back.calibration["supply_area_scale.elbow.a"] == est(1.2, 0.01)
    assert np.isnan(back.calibration["armature_scale.elbow"]["stderr"])
    assert [e.family for e in back.effects] == [e.family for e in full_model().effects]
    assert back.unexplained[0]["evidence"] == "a \"smooth\" torque removes 30 %"


def test_load_robot_applies_the_calibration_and_carries_the_effects(arm2, tmp_path):
    path = write_fitted(full_model(), tmp_path / "model.toml")
    with pytest.warns(FittedModelWarning, match=r"unexplained\]\] #1.*joint elbow"):
        fitted = load_robot("arm2", fitted=path)
    nom, fit = arm2.tables, fitted.tables
    c = {f"{a}.{ch}": i for i, (a, ch) in enumerate(arm2.chamber_names)}
    assert fit.valve[c["elbow.a"], 6] == pytest.approx(1.2 * nom.valve[c["elbow.a"], 6])     # supply area max
    assert fit.valve[c["elbow.a"], 7] == nom.valve[c["elbow.a"], 7]
    assert fit.valve[c["shoulder.b"], 7] == pytest.approx(0.9 * nom.valve[c["shoulder.b"], 7])  # exhaust
    assert fit.dead_volume[c["elbow.b"]] == pytest.approx(1.3 * nom.dead_volume[c["elbow.b"]])
    b = arm2.model.body("forearm").id
    assert fitted.model.body_mass[b] == pytest.approx(1.1 * arm2.model.body_mass[b])
    np.testing.assert_allclose(fitted.model.body_inertia[b], 1.1 * arm2.model.body_inertia[b])
    d = arm2.model.joint("shoulder").dofadr[0]
    assert fitted.model.dof_damping[d] == pytest.approx(1.25 * arm2.model.dof_damping[d])
    e = arm2.model.joint("elbow").dofadr[0]
    assert fitted.model.dof_armature[e] == pytest.approx(1.5 * arm2.model.dof_armature[e])
    assert arm2.model.body_mass[b] == pytest.approx(0.45)  # the nominal robot is untouched
    assert fitted.effects.valve_leak_m2["elbow.a"] == 2e-8 and fitted.fitted.model == "arm2"


def test_a_simulation_of_a_fitted_robot_runs_its_effects(tmp_path):
    """A piston leak in the fitted model equalises the shoulder's chambers, which the nominal
    model keeps apart (valves at null are nearly shut)."""
    from pneumatics.sim import Simulation

    fm = FittedModel("arm2", effects=[effect("piston_leak", "orifice", {"actuator": "shoulder"}, leak_area_m2=2e-7)])
    gaps = []
    for robot in (load_robot("arm2"), load_robot("arm2", fitted=write_fitted(fm, tmp_path / "m.toml"))):
        sim = Simulation(robot)
        sim.model.eq_active0[sim.model.equality("brace_shoulder").id] = 1
        sim.reset(pressure_pa=[6e5, 2e5, 4e5, 4e5])
        sim.step(200)
        p = sim.observe().p
        gaps.append(p[0] - p[1])
    assert gaps[1] < 0.5 * gaps[0]


def test_an_end_stop_is_applied_at_its_angle_and_says_what_is_approximate(arm2):
    fm = FittedModel("arm2", effects=[FittedEffect("end_stop", "spring_damper", {"joint": "elbow"},
                                                   {"stiffness_nm_per_rad": est(200.0, 10.0),
                                                    "damping_nm_s_per_rad": est(0.5, 0.1),
                                                    "stop_rad": est(1.0, 0.01), "side_sign": est(1.0)})])
    with pytest.warns(FittedModelWarning, match="end_stop at elbow.*stiffness 200 N m/rad.*not"):
        robot = load_robot("arm2", fitted=fm)
    hi = arm2.model.jnt_range[arm2.model.joint("elbow").id][1]
    assert robot.effects.end_stop["elbow"]["upper_intrusion_rad"] == pytest.approx(hi - 1.0)
    _, mm = replay_mods(robot)  # the doctor's replay keeps the fitted spring
    assert mm.end_stops[1] == (1.0, 1.0) and mm.end_stop_nm_per_rad[1] == 200.0


def test_an_entry_the_simulator_has_no_place_for_is_kept_and_named(arm2, tmp_path):
    """A load-cell offset (the bench doctor's) stays in the file and is a warning at load."""
    fm = FittedModel("arm2", effects=[effect("force_sensor_offset", "additive", {"actuator": "elbow"}, offset_n=1.5)])
    path = write_fitted(fm, tmp_path / "model.toml")
    with pytest.warns(FittedModelWarning, match=r"\[\[effect\]\] #1 \(force_sensor_offset at elbow\).*not applied"):
        robot = load_robot("arm2", fitted=path)
    assert robot.effects.empty and robot.fitted.effects[0].value("offset_n") == 1.5


def test_bad_fitted_files_are_one_clear_error(tmp_path):
    good = fitted_text(full_model())
    cases = {
        "model": (good.replace('name = "arm2"', 'name = "humanoid38"'), "fitted to model 'humanoid38', not 'arm2'"),
        "place": (good.replace('"mass_scale.forearm"', '"mass_scale.forarm"'), r"no body 'forarm'; valid: .*forearm"),
        "chamber": (good.replace('chamber = "a" }\n[effect.parameters]\nleak_area_m2 = { value = 2e-08',
                                 'chamber = "c" }\n[effect.parameters]\nleak_area_m2 = { value = 2e-08'),
                    r"#1 \(valve_leak at elbow.c\): arm2 has no chamber 'elbow.c'"),
        "form": (good.replace('form = "orifice"', 'form = "sharp_edged"', 1), "unknown form 'sharp_edged' of external_leak"),
        "param": (good.replace("half_width_v", "half_width_mv"), r"form play needs parameters half_width_v.*half_width_mv"),
        "value": (good.replace("{ value = 1.1, stderr", "{ value = -1.1, stderr"), r"mass_scale.forearm'.value = -1.1"),
        "format": (good.replace("format_version = 1", "format_version = 7"), "format_version = 7"),
        "toml": (good.replace("[model]", "[model"), "not valid TOML"),
    }
    for name, (text, message) in cases.items():
        path = tmp_path / f"{name}.toml"
        path.write_text(text)
        with pytest.raises(PneumasimError, match=message) as err, warnings.catch_warnings():
            warnings.simplefilter("ignore", FittedModelWarning)
            load_robot("arm2", fitted=path)
        assert str(path) in str(err.value) or name in ("chamber", "form", "param")
    (tmp_path / "family.toml").write_text(good.replace('family = "valve_lag"', 'family = "valve_slag"'))
    with pytest.raises(UnknownNameError, match="valve_slag"):
        read_fitted(tmp_path / "family.toml")
    with pytest.raises(ConfigError, match="not found"):
        read_fitted(tmp_path / "missing.toml")


def test_fitted_xml_loads_in_mujoco_and_steps_without_warnings(arm2, tmp_path):
    fm = full_model()
    fm.effects.append(FittedEffect("end_stop", "spring_damper", {"joint": "shoulder"},
                                   {"stiffness_nm_per_rad": est(200.0), "damping_nm_s_per_rad": est(0.5),
                                    "stop_rad": est(-0.9, 0.01), "side_sign": est(-1.0)}))
    path = write_fitted_mjcf(arm2, fm, tmp_path / "fitted.xml")
    text = path.read_text()
    assert "Not in this file" in text and "valve_leak at elbow.a" in text and "chamber calibration" in text
    m = mujoco.MjModel.from_xml_path(str(path))
    b, s, e = m.body("forearm").id, m.joint("shoulder").dofadr[0], m.joint("elbow").dofadr[0]
    assert m.body_mass[b] == pytest.approx(1.1 * arm2.model.body_mass[b], rel=1e-5)   # MJCF keeps 6 digits
    np.testing.assert_allclose(m.body_inertia[b], 1.1 * arm2.model.body_inertia[b], rtol=1e-5)
    assert m.dof_damping[s] == pytest.approx(1.25 * arm2.model.dof_damping[s], rel=1e-5)
    assert m.dof_damping[e] == pytest.approx(arm2.model.dof_damping[e] + 0.01, rel=1e-5)  # viscous friction
    assert m.dof_frictionloss[s] == pytest.approx(0.04, rel=1e-5) and m.dof_frictionloss[e] == 0
    assert m.dof_armature[e] == pytest.approx(1.5 * arm2.model.dof_armature[e], rel=1e-5)
    assert m.jnt_range[m.joint("shoulder").id][0] == pytest.approx(-0.9, abs=1e-5)
    d = mujoco.MjData(m)
    d.ctrl[:] = [30.0, -40.0]  # cylinder forces [N]: the shoulder runs into its stop
    for _ in range(3000):
        mujoco.mj_step(m, d)
    assert all(w.number == 0 for w in d.warning)
    assert d.qpos[m.joint("shoulder").qposadr[0]] > -0.95 and np.all(np.isfinite(d.qpos))


@needs_samples
def test_the_loaded_model_replays_as_the_doctors_own_modifications_do():
    """The calibration baked into the loaded robot and the effects through the doctor's own
    hypotheses give the same coupled replay as the doctor's representation of that model
    (scales in PneumaticMods and MechMods on the nominal robot): a 6 s held-out slice."""
    fm = full_model()
    fm.effects = [c[0] for c in CASES if c[1] in ("valve_leak_m2", "piston_leak_m2", "friction", "pressure_offset_pa")]
    rec = split(read_csv(BLIND / "case_befd9d0f_heldout.csv"), 0.2)[1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FittedModelWarning)
        fitted = load_robot("arm2", fitted=fm)
    loaded = heldout_replay(fitted, [rec]).nrmse()
    nominal = load_robot("arm2")
    pm, mm = replay_mods(fitted)
    C = nominal.tables.n_chambers
    names = [f"{a}.{c}" for a, c in nominal.chamber_names]
    pm = pm.copy(supply_scale=np.array([fm.scale("supply_area_scale", n) for n in names]),
                 exhaust_scale=np.array([fm.scale("exhaust_area_scale", n) for n in names]),
                 dead_volume_scale=np.array([fm.scale("dead_volume_scale", n) for n in names]))
    assert pm.supply_scale.size == C
    mm.mass_scale = {"forearm": 0.1}
    mm.damping_scale = {"shoulder": 0.25}
    mm.armature_scale = {"elbow": 0.5}
    direct = coupled_replay(prepare(nominal, rec), pm, mm).nrmse()
    for ch, v in direct.items():
        assert loaded[ch] == pytest.approx(v, rel=1e-9), ch
    base = coupled_replay(prepare(nominal, rec), PneumaticMods.nominal(C), MechMods()).nrmse()
    assert any(abs(loaded[ch] / base[ch] - 1) > 0.01 for ch in base)  # the model made a difference


@needs_samples
@pytest.mark.slow
def test_a_doctor_runs_model_toml_reproduces_its_heldout_numbers(tmp_path):
    """The doctor on the published LuGre-shoulder case (about a minute): model.toml reloads,
    replays the held-out recording through the doctor's replay code to the report's
    after-NRMSE (to 1e-9: the same arithmetic, up to the order of a few products), writes back
    byte for byte, and fitted.xml steps in MuJoCo without warnings."""
    from identification.doctor.valve_arm.diagnose import diagnose
    from identification.doctor.valve_arm.report import write

    robot = load_robot("arm2")
    held = [read_csv(BLIND / "case_befd9d0f_heldout.csv")]
    report = diagnose(robot, [read_csv(BLIND / "case_befd9d0f.csv")], held)
    write(report, tmp_path, robot, rerun=False)
    assert (tmp_path / "model.toml").read_text() == fitted_text(read_fitted(tmp_path / "model.toml"))
    fitted = load_robot("arm2", fitted=tmp_path / "model.toml")
    assert [(e.family, e.form, e.where) for e in fitted.fitted.effects] == [
        ("coulomb_friction", "coulomb", {"joint": "shoulder"})]
    assert report["findings"][0]["form"] == "coulomb"
    after = heldout_replay(fitted, held).nrmse()
    for ch, v in report["after"]["heldout_nrmse"].items():
        assert after[ch] == pytest.approx(v, rel=1e-9), ch
    f = report["findings"][0]
    assert after[f["heldout_channel"]] == pytest.approx(f["heldout_nrmse"]["after"], rel=1e-9)
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "fitted.xml"))
    assert m.dof_frictionloss[m.joint("shoulder").dofadr[0]] == pytest.approx(
        fitted.fitted.effects[0].value("coulomb_nm"), rel=1e-5)
    d = mujoco.MjData(m)
    for _ in range(2000):
        mujoco.mj_step(m, d)
    assert all(w.number == 0 for w in d.warning)


def test_run_fitted_refuses_a_scenario_without_one_and_another_robots_model(tmp_path):
    from scenarios.common import fitted_scenarios, run_scenario

    assert {"arm2_step_response", "arm2_tracking"} <= set(fitted_scenarios())
    path = write_fitted(full_model(), tmp_path / "model.toml")
    with pytest.raises(PneumasimError, match=r"arm2_asymptotic_pressure does not take --fitted; .*arm2_step_response \(arm2\)"):
        run_scenario("arm2_asymptotic_pressure", tmp_path / "out", fast=True, fitted=path)
    other = tmp_path / "humanoid.toml"
    other.write_text(path.read_text().replace('name = "arm2"', 'name = "humanoid38"'))
    with pytest.raises(PneumasimError, match="fitted to model 'humanoid38', but scenario arm2_step_response simulates 'arm2'"):
        run_scenario("arm2_step_response", tmp_path / "out", fast=True, fitted=other)


def test_run_fitted_simulates_the_fitted_robot(tmp_path):
    """arm2_step_response on a model whose forearm is 50 % heavier: the same cylinder force
    accelerates it less, so the step's peak velocity drops (seen: 1278 against 1507 deg/s)."""
    from scenarios.common import run_scenario

    fm = FittedModel("arm2", calibration={"mass_scale.forearm": est(1.5, 0.01)})
    path = write_fitted(fm, tmp_path / "model.toml")
    nominal = run_scenario("arm2_step_response", tmp_path / "nominal", fast=True, quiet=True)
    fitted = run_scenario("arm2_step_response", tmp_path / "fitted", fast=True, quiet=True, fitted=path)
    assert fitted["fitted_model"] == str(path)
    assert fitted["peak_velocity_deg_s"] < 0.9 * nominal["peak_velocity_deg_s"]


def test_a_humanoid_fitted_model_loads_and_its_mjcf_steps(tmp_path):
    """The same files for the 38-DOF humanoid: a heavier torso link, a damper and a Coulomb
    level at the waist roll, a wider valve; fitted.xml compiles and steps without warnings."""
    nominal = load_robot("humanoid38")
    body, joint, act = "waist_pitch_link", "waist_roll", nominal.actuator_names[0]
    fm = FittedModel("humanoid38", calibration={f"mass_scale.{body}": est(1.2), f"damping_scale.{joint}": est(1.1),
                                                f"supply_area_scale.{act}.a": est(1.1)},
                     effects=[effect("coulomb_friction", "coulomb", {"joint": joint}, coulomb_nm=0.1)])
    robot = load_robot("humanoid38", fitted=write_fitted(fm, tmp_path / "model.toml"))
    b = nominal.model.body(body).id
    assert robot.model.body_mass[b] == pytest.approx(1.2 * nominal.model.body_mass[b])
    assert robot.effects.friction == {joint: {"coulomb_nm": 0.1}}
    m = mujoco.MjModel.from_xml_path(str(write_fitted_mjcf(nominal, fm, tmp_path / "fitted.xml")))
    assert m.body_mass[m.body(body).id] == pytest.approx(1.2 * nominal.model.body_mass[b], rel=1e-5)
    assert m.dof_frictionloss[m.joint(joint).dofadr[0]] == pytest.approx(0.1)
    d = mujoco.MjData(m)
    for _ in range(1000):
        mujoco.mj_step(m, d)
    assert all(w.number == 0 for w in d.warning)


def test_a_tube_the_doctor_fitted_into_the_dead_volume_is_counted_once(arm2):
    """line_dynamics: the doctor fits tube + chamber as one dead-volume scale (1.8 here); the
    file gives the tube what grew past nominal and the chamber a scale of 1, and the loaded
    model's total dead volume is the fitted one."""
    from identification.doctor.valve_arm.fitted_model import fitted_model

    report = {"model": "arm2", "calibrated_with_findings": {"dead_volume_scale.elbow.b": 1.8, "mass_scale.forearm": 1.05},
              "findings": [{"effect": "line_dynamics", "where": {"actuator": "elbow", "chamber": "b"}},
                           {"effect": "stiction", "where": {"joint": "shoulder"}}],
              "unexplained": [], "after": {"heldout_nrmse": {"q.elbow": 0.01}},
              "diagnostics": {"train_sources": ["a.csv"], "heldout_sources": "last 30 % of each recording"}}
    params = [{"delay_s": est(0.012, 0.001), "volume_m3": est(1.0, 1.0)},
              {"coulomb_nm": est(0.03, 0.001), "breakaway_extra_nm": est(0.02, 0.002)}]
    fm = fitted_model(arm2, report, params, {"dead_volume_scale.elbow.b": 0.09, "mass_scale.forearm": 0.01})
    c = [f"{a}.{ch}" for a, ch in arm2.chamber_names].index("elbow.b")
    nominal = arm2.tables.dead_volume[c]
    assert fm.calibration["dead_volume_scale.elbow.b"]["value"] == 1.0
    tube = fm.effects[0].parameters["volume_m3"]
    assert tube["value"] == pytest.approx(0.8 * nominal) and tube["stderr"] == pytest.approx(0.09 * nominal)
    assert fm.effects[1].form == "stribeck" and fm.effects[1].value("stribeck_rad_s") == 0.1
    robot = load_robot("arm2", fitted=fm)
    delay, volume = robot.effects.line_arrays(robot)
    assert robot.tables.dead_volume[c] + volume[c] == pytest.approx(1.8 * nominal) and delay[c] == 0.012
    assert fm.heldout_on == ["last 30 % of each recording"] and fm.calibration["mass_scale.forearm"]["stderr"] == 0.01
