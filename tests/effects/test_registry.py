"""The registry of effect families: names, lookups, parameters with units, and the docs table."""
import re
from pathlib import Path

import numpy as np
import pytest

from pneumatics.effects import VOCABULARY
from pneumatics.effects.effect_set import EffectSet
from pneumatics.effects.family import DOCTOR_SIDES, PLACE_KINDS, place_names
from pneumatics.effects.registry import FAMILIES, families_of, get_family, markdown_table
from pneumatics.errors import ConfigError, UnknownNameError

DESIGN_VOCABULARY = {"coulomb_friction", "stiction", "viscous_friction", "valve_leak", "piston_leak", "valve_hysteresis",
                     "valve_lag", "line_dynamics", "heat_transfer", "pressure_sensor_offset", "angle_sensor_offset",
                     "supply_droop", "end_stop", "backlash", "external_leak", "force_sensor_offset"}


def test_the_registry_holds_the_design_vocabulary_once_each():
    assert set(VOCABULARY) == DESIGN_VOCABULARY and len(VOCABULARY) == len(DESIGN_VOCABULARY)
    for name, fam in FAMILIES.items():
        assert fam.name == name and fam.place_kind in PLACE_KINDS and fam.forms and fam.sources and fam.physics
        assert fam.doctor in DOCTOR_SIDES and fam.plants


def test_an_unknown_family_or_form_names_the_valid_ones():
    with pytest.raises(UnknownNameError, match="valid: angle_sensor_offset, backlash"):
        get_family("valve_leek")
    with pytest.raises(UnknownNameError, match="valid: laminar, orifice"):
        get_family("external_leak").params({"leak_area_m2": 1e-8}, "capillary")


def test_parameters_are_checked_against_their_units():
    lag = get_family("valve_lag")
    assert lag.params({"time_constant_s": 0.03}).time_constant_s == 0.03
    with pytest.raises(ConfigError, match="time_constant_s = 30 is outside"):
        lag.params({"time_constant_s": 30.0})  # 30 "s": milliseconds typed as seconds
    with pytest.raises(ConfigError, match="did you mean 'time_constant_s'"):
        lag.params({"time_constant_ms": 30.0})
    with pytest.raises(ConfigError, match="side: expected one of upper, lower, got 'uper'"):
        get_family("end_stop").params({"side": "uper", "intrusion_rad": 0.2}, "soft_limit")


def test_every_arm_family_switches_its_effect_on_in_an_effect_set(arm2):
    rng = np.random.default_rng(0)
    for fam in families_of("valve_arm"):
        place = place_names(arm2, fam.place_kind)[0]
        effects = EffectSet()
        fam.add_to(effects, place, fam.draw(rng))
        assert not effects.empty, fam.name


def test_friction_terms_at_one_joint_add_up():
    effects = EffectSet()
    get_family("coulomb_friction").add_to(effects, "elbow", get_family("coulomb_friction").params({"coulomb_nm": 0.1}))
    get_family("viscous_friction").add_to(effects, "elbow",
                                          get_family("viscous_friction").params({"viscous_nm_s_per_rad": 0.2}))
    assert effects.friction == {"elbow": {"coulomb_nm": 0.1, "viscous_nm_s": 0.2}}


def test_scaling_keeps_shapes_and_moves_an_end_stop_towards_the_margin():
    st = get_family("stiction")
    half = st.scaled(st.params({"coulomb_nm": 0.04, "breakaway_extra_nm": 0.1, "stribeck_rad_s": 0.1}), 0.5)
    assert (half.coulomb_nm, half.breakaway_extra_nm, half.stribeck_rad_s) == (0.02, 0.05, 0.1)
    stop = get_family("end_stop")
    moved = stop.scaled(stop.params({"side": "lower", "intrusion_rad": 0.2}, "soft_limit"), 0.5)
    assert moved.side == "lower" and np.radians(5.0) < moved.intrusion_rad < 0.2


def test_the_case_makers_use_registered_names():
    from scenarios._cases import BENCHMARK_FAMILIES
    from scenarios._cases import FAMILIES as ARM_CASES
    from scenarios._jetpipe_cases import FAMILIES as JETPIPE_CASES
    from scenarios._variantsim.effects import FAMILIES as VARIANT_CASES

    assert set(ARM_CASES) == {f.name for f in families_of("valve_arm")}
    assert "end_stop" not in BENCHMARK_FAMILIES
    assert all("jetpipe" in get_family(n).plants for n in JETPIPE_CASES)
    assert set(VARIANT_CASES) <= set(VOCABULARY)


def test_the_docs_table_is_the_registrys():
    text = (Path(__file__).resolve().parents[2] / "docs" / "effects.md").read_text()
    table = text[text.index("| family | place |"):]
    assert table == markdown_table()
    for name in VOCABULARY:
        assert re.search(rf"^\| `{name}` \|", table, re.M)


def test_an_effect_set_switches_a_family_on_by_name_with_checked_units():
    effects = EffectSet().add("valve_lag", "elbow.b", {"time_constant_s": 0.03}).add(
        "supply_droop", "all", {"droop_pa_per_kg_s": 5e7})
    assert effects.valve_lag_s == {"elbow.b": 0.03} and effects.supply_droop_pa_per_kg_s == 5e7
    with pytest.raises(ConfigError, match="leak_area_m2"):
        EffectSet().add("external_leak", "elbow.a", {"leak_area_m2": 2.0})  # 2 m^2: mm^2 typed as m^2


def test_the_doctors_hypotheses_report_the_families_parameters(arm2):
    """Every parameter a hypothesis fits is a field of one form of its family, so a finding's
    parameters are the family definition's (and go back into the simulator through it)."""
    import dataclasses

    from identification.doctor.valve_arm.hypotheses import mechanical_hypotheses, pneumatic_hypotheses

    for h in pneumatic_hypotheses(arm2) + mechanical_hypotheses(arm2):
        names = [p[0] for p in h.params] + list(h.fixed)
        fields = [{f.name for f in dataclasses.fields(cls)} for cls in get_family(h.family).forms.values()]
        assert any(set(names) <= f for f in fields), (h.family, names)


def _every_form_at_small_values():
    """(family, form, params) for every form of every arm family, each magnitude at 1e-9."""
    import dataclasses

    for fam in families_of("valve_arm"):
        for form, cls in fam.forms.items():
            values = {f.name: 1e-9 for f in dataclasses.fields(cls) if f.metadata.get("magnitude", True)}
            yield fam, form, cls(**values)


def test_every_effect_set_field_is_written_by_a_family():
    """No effect reaches the simulator except through a family definition."""
    import dataclasses

    written = set()
    for fam, form, params in _every_form_at_small_values():
        if (fam.name, form) != ("end_stop", "spring_damper"):  # the doctor's form of the bumper
            written |= set(fam.effect_set_entry(params))
    assert written == {f.name for f in dataclasses.fields(EffectSet)} - {"valve_leak_width_v"}


def _same(a, b) -> bool:
    if a is None or b is None:
        return a is b
    return np.array_equal(a, b, equal_nan=True)


def test_every_effect_field_of_the_doctors_chamber_model_is_filled_by_a_family(arm2):
    """No effect reaches the doctor's pressure replays except through a family definition."""
    import dataclasses

    from identification.doctor.valve_arm.pneumatic_mods import PneumaticMods

    nominal = PneumaticMods.nominal(arm2.tables.n_chambers)
    filled = set()
    for fam, form, params in _every_form_at_small_values():
        if fam.doctor != "pressure_replay":
            continue
        place = place_names(arm2, fam.place_kind)[0]
        mods = fam.apply_to_mods(nominal, arm2, place, params)
        filled |= {f.name for f in dataclasses.fields(mods) if not _same(getattr(mods, f.name), getattr(nominal, f.name))}
    calibration = {"supply_scale", "exhaust_scale", "dead_volume_scale", "valve_leak_width_v"}
    # outside the vocabulary on purpose: a wall that yields, fitted only to tell it from a
    # line's volume (identification/doctor/valve_arm/compliance.py), never a finding
    outside = {"wall_compliance_m3_pa"}
    # the receiver's path along each recording its fit left (supply_receiver), and the supply's
    # path held for a candidate's fit at its cylinders (supply_path): the fits', not parameters
    fitted_paths = {"receiver_paths", "supply_paths"}
    assert filled == {f.name for f in dataclasses.fields(PneumaticMods)} - calibration - outside - fitted_paths


def test_a_hook_a_family_does_not_have_says_so():
    from pneumatics.effects.family import NotOnThisSide

    offset = get_family("force_sensor_offset")
    with pytest.raises(NotOnThisSide, match="no load cell"):
        offset.add_to(EffectSet(), "elbow", offset.params({"offset_n": 1.0}))
    stop = get_family("end_stop")
    with pytest.raises(NotOnThisSide, match="soft_limit form"):
        stop.effect_set_entry(stop.params({"stop_rad": 0.5, "stiffness_nm_per_rad": 100.0}, "spring_damper"))
    lag = get_family("valve_lag")
    with pytest.raises(NotOnThisSide, match="torque balance"):
        lag.torque_balance_term(None, None, 0, lag.params({"time_constant_s": 0.01}))
