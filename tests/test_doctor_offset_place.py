"""Where the doctor places a pressure-sensor offset that the torque balance sees as a cylinder
force error (identification/doctor/valve_arm/search.py: offset_place, fixed_offset_gains), on
a recording of the random-form generator diagnosed from its CSV files alone."""
import pytest

from identification.doctor.valve_arm.diagnose import diagnose
from pneumatics.recording import read_csv
from pneumatics.robot import load_robot


def test_a_pressure_offset_the_free_fits_cannot_place_is_placed_by_the_torque_balances_offset(tmp_path):
    """A +4.9 kPa zero offset of shoulder a's transducer (random-form generator, seed 488402070
    of fresh generalization run 9, where it was named at the actuator): freely fitted in each
    chamber's replays neither pays clearly; the torque balance's offset put into chamber a's
    sensor improves a's held-out replay (the calibration refitted), into b's (-5.8 kPa) makes
    b's worse, so the finding names chamber a alone."""
    from scenarios._variantsim.cases import make_case as make_variant_case

    truth = make_variant_case(tmp_path / "c", 488402070, ["pressure_sensor_offset"], seconds=60.0,
                              heldout_seconds=30.0, name="offset")
    assert truth["effects"][0]["where"] == {"actuator": "shoulder", "chamber": "a"}
    report = diagnose(load_robot("arm2"), [read_csv(truth["recordings"]["main"])],
                      [read_csv(truth["recordings"]["heldout"])])
    first = report["findings"][0]
    assert first["effect"] == "pressure_sensor_offset" and first["where"] == {"actuator": "shoulder", "chamber": "a"}
    assert first["alternative_places"] == []
    assert first["parameters"]["offset_pa"]["value"] == pytest.approx(
        truth["effects"][0]["effective"]["offset_pa"], rel=0.15)
