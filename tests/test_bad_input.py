"""Bad input gets one clear line naming what is wrong (issue: simulator core, 'Bad input')."""
import warnings

import numpy as np
import pytest

from pneumatics.errors import ConfigError, PneumasimError, UnknownNameError
from pneumatics.params import load_fluid, parse_fluid
from pneumatics.robot import compile_mjcf, load_robot
from pneumatics.sim import CommandClippedWarning, Simulation

import models
import tomllib

ARM2_TOML = tomllib.loads(models.fluid_path("arm2").read_text())


def doc_with(**changes):
    import copy
    doc = copy.deepcopy(ARM2_TOML)
    for path, value in changes.items():
        *keys, last = path.split("__")
        t = doc
        for k in keys:
            t = t[int(k)] if k.isdigit() else t[k]
        if value is None:
            del t[last]
        else:
            t[last] = value
    return doc


def test_unknown_model_lists_the_valid_names():
    with pytest.raises(UnknownNameError, match=r"unknown model 'arm3'; did you mean 'arm2'\? valid: .*arm2"):
        load_robot("arm3")


def test_missing_field_is_named():
    with pytest.raises(ConfigError, match=r"\(elbow\): missing field 'dead_volume_b_m3' \(m\^3\)"):
        parse_fluid(doc_with(actuator__1__dead_volume_b_m3=None), "fluid.toml")


def test_wrong_unit_suffix_points_at_the_right_field():
    doc = doc_with(actuator__0__bore_m=None)
    doc["actuator"][0]["bore_mm"] = 20
    with pytest.raises(ConfigError, match="unknown field 'bore_mm' \\(did you mean 'bore_m', in m\\?\\)"):
        parse_fluid(doc, "fluid.toml")


def test_value_in_the_wrong_unit_is_caught_by_its_range():
    with pytest.raises(ConfigError, match=r"bore_m = 20 is outside the plausible range .* \(is it in the wrong unit\?\)"):
        parse_fluid(doc_with(actuator__0__bore_m=20), "fluid.toml")
    with pytest.raises(ConfigError, match="supply_pa = 6 is outside"):
        parse_fluid(doc_with(supply__supply_pa=6), "fluid.toml")


def test_wrong_type_and_shape():
    with pytest.raises(ConfigError, match="expected a number in m, got 'twenty'"):
        parse_fluid(doc_with(actuator__0__stroke_m="twenty"), "fluid.toml")
    with pytest.raises(ConfigError, match=r"\[valve\].*expected a number"):
        parse_fluid(doc_with(valve__null_v=[5.0, 5.0]), "fluid.toml")
    with pytest.raises(ConfigError, match="unknown table \\[valves\\]"):
        parse_fluid({**ARM2_TOML, "valves": {}}, "fluid.toml")


def test_gauge_supply_pressure_is_rejected():
    with pytest.raises(ConfigError, match="must exceed room_pa"):
        parse_fluid(doc_with(supply__supply_pa=1.2e5, supply__room_pa=1.5e5), "f.toml")


def test_toml_syntax_error_names_the_file(tmp_path):
    f = tmp_path / "fluid.toml"
    f.write_text("[gas\nx=1")
    with pytest.raises(ConfigError, match=f"{f}: not valid TOML"):
        load_fluid(f)


def test_malformed_mjcf_is_one_line(tmp_path):
    f = tmp_path / "bad.xml"
    f.write_text("<mujoco><worldbody><body><joint type='hinge' axis='0 0 0'/></body></worldbody></mujoco>")
    with pytest.raises(ConfigError) as e:
        compile_mjcf(f)
    assert str(f) in str(e.value) and "\n" not in str(e.value)


def test_fluid_actuator_without_mjcf_actuator():
    doc = doc_with(actuator__1__name="wrist")
    with pytest.raises(ConfigError, match="fluid actuator 'wrist' has no MJCF actuator"):
        load_robot("arm2", fluid=parse_fluid(doc, "f.toml"))


def test_commands_outside_the_range_are_clipped_with_one_warning(arm2):
    sim = Simulation(arm2)
    with pytest.warns(CommandClippedWarning, match="clipped; warned once per run"):
        sim.set_command([12.0, -1.0, 5.0, 5.0])
    assert list(sim.command[:2]) == [10.0, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.set_command([11.0, 5.0, 5.0, 5.0])  # no second warning in the same run


def test_nan_commands_raise_and_name_the_chamber(arm2):
    sim = Simulation(arm2)
    with pytest.raises(PneumasimError, match="NaN or inf for chamber\\(s\\) elbow.b"):
        sim.set_command([5.0, 5.0, 5.0, np.nan])
    with pytest.raises(PneumasimError, match="expected shape \\(4,\\)"):
        sim.set_command([5.0, 5.0])
