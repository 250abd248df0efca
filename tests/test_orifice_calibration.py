"""Orifice-area calibration (paper 002 eqs. 10-12) and the per-valve linearising transform."""
import numpy as np
import pytest

from controllers.linearize import (
    ValveLinearizer,
    canonical_command,
    canonical_opening,
    net_opening,
)
from identification.orifice import (
    OrificeCalibration,
    Transient,
    calibrate_robot,
    calibration_errors,
    fit_orifice_areas,
    locked_robot,
    relative_errors,
    true_areas,
)
from pneumatics.chamber import static_transient
from pneumatics.errors import PneumasimError
from pneumatics.medium import GasCfg
from pneumatics.sim import Simulation
from pneumatics.valve import VALVE_COLUMNS, ValveCfg

GAS = GasCfg()
SUPPLY, ROOM = 7e5, 1e5


def three_valves() -> np.ndarray:
    """(3, 8) valve rows: the default map, one shifted and skewed, one small and steep."""
    rows = [ValveCfg().as_row(),
            ValveCfg(null_v=5.12, deadband_v=0.22, opening_exponent=1.5, supply_area_max_m2=5e-7).as_row(),
            ValveCfg(null_v=4.87, deadband_v=0.1, opening_exponent=1.1, exhaust_area_max_m2=4e-7).as_row()]
    return np.array(rows)


def synthetic_transients(rows, volume, commands, rng, noise_pa=1000.0, duration_s=1.0):
    """Static-volume transients from the numpy reference ODE (independent of the MuJoCo path),
    every (valve, command, start pressure) integrated at once; 1 kHz samples with white noise."""
    n, m = len(rows), len(commands)
    cmd = np.repeat(np.tile(np.asarray(commands, float), 2), n)        # (2 m n,) p0-major
    p0 = np.repeat([ROOM, SUPPLY], m * n)
    t, p = static_transient(np.tile(rows, (2 * m, 1)), np.tile(volume, 2 * m), p0, cmd, duration_s, 1e-3,
                            GAS, SUPPLY, ROOM)
    p = p + rng.normal(0.0, noise_pa, p.shape)
    out = []
    for k in range(2 * m):
        cols = slice(k * n, (k + 1) * n)
        out.append(Transient(t[2:], p[2:, cols], cmd[cols], float(p0[k * n])))
    return out


@pytest.fixture(scope="module")
def synthetic():
    rows = three_valves()
    volume = np.array([1.5e-5, 8e-6, 1.1e-5])
    commands = np.array([0.0, 3.0, 4.7, 5.0, 5.3, 7.0, 10.0])
    tr = synthetic_transients(rows, volume, commands, np.random.default_rng(0))
    return rows, volume, fit_orifice_areas(tr, GAS, SUPPLY, ROOM, volume_m3=volume)


def test_regression_recovers_known_maps_with_honest_standard_errors(synthetic):
    rows, _, cal = synthetic
    t_c, t_r = true_areas(rows, cal.commands_v)
    e_c, e_r = cal.areas()
    err = np.concatenate([relative_errors(e_c, t_c), relative_errors(e_r, t_r)])
    assert np.median(err) < 0.01 and err.max() < 0.05
    # near the null both ports leak a few per cent of full area: recovered to 0.2 % of full
    full_c = t_c.max(axis=1)
    k = list(cal.commands_v).index(5.0)
    assert np.all(np.abs(e_c[:, k] - t_c[:, k]) < 2e-3 * full_c)
    s_c, _ = cal.area_stderr()
    assert np.all(s_c > 0) and np.all(np.isfinite(s_c))


def test_eqs_11_12_need_no_volume(synthetic):
    rows, volume, cal = synthetic
    t_c, t_r = true_areas(rows, cal.commands_v)
    wrong = OrificeCalibration(cal.commands_v, cal.charge_per_volume, cal.discharge_per_volume, cal.charge_se,
                               cal.discharge_se, volume * 1.3)
    a_c, _ = wrong.anchored(t_c[:, -1], t_r[:, 0])  # the data-sheet areas at 10 V and 0 V
    assert np.median(relative_errors(a_c, t_c)) < 0.01
    assert np.median(relative_errors(wrong.areas()[0], t_c)) == pytest.approx(0.3, abs=0.02)


def test_transients_need_one_command_per_record():
    tr = Transient(np.arange(10) * 1e-3, np.full((10, 2), 2e5), np.array([4.0, 6.0]), ROOM)
    with pytest.raises(PneumasimError, match="one command"):
        fit_orifice_areas([tr], GAS, SUPPLY, ROOM)


def test_locked_joints_keep_the_volume_static(arm2):
    sim = Simulation(locked_robot(arm2), kernel="reference")
    sim.reset(pressure_pa=ROOM)
    q0 = sim.observe().q.copy()
    sim.set_command(np.array([10.0, 0.0, 0.0, 10.0]))  # full force on both joints
    sim.step(150)
    assert np.abs(sim.observe().q - q0).max() < 2e-3  # rad; free, the arm would swing ~1 rad
    assert sim.pressure[0] > 5e5


def test_calibration_on_the_simulated_arm(arm2):
    cal = calibrate_robot(arm2, np.array([0.0, 10.0]), duration_scale=0.25, kernel="reference")
    err = calibration_errors(cal, arm2.tables.valve)
    assert np.median(err["volume"]) < 0.03
    assert np.median(err["closed_abs_frac"]) < 0.01
    assert cal.chamber_names == arm2.chamber_names


# -- linearising transform --------------------------------------------------------------------

def test_canonical_sigmoid_is_odd_monotone_and_inverted():
    u = np.linspace(0, 10, 101)
    y = canonical_opening(u)
    assert y[0] == pytest.approx(-1) and y[-1] == pytest.approx(1) and canonical_opening(5.0) == 0
    assert np.all(np.diff(y) > 0) and np.allclose(y, -y[::-1])
    assert np.allclose(canonical_command(y), u, atol=1e-9)


def test_transform_makes_every_valve_the_canonical_sigmoid():
    rows = three_valves()
    lin = ValveLinearizer.from_valve_rows(rows)
    u = np.linspace(0.2, 9.8, 49)
    for uk in u:
        v = lin(np.full(3, uk))
        a_s, a_e = true_areas(rows, np.linspace(0, 10, 1001))
        h_true = [np.interp(v[i], np.linspace(0, 10, 1001), net_opening(a_s, a_e)[i]) for i in range(3)]
        assert np.allclose(h_true, canonical_opening(uk), atol=2e-3)
    # the canonical 5 V lands in (or within 0.05 V of) each valve's own dead band around its own
    # null: where the two ports' openings, each relative to its largest, balance; a valve whose
    # null is off 5 V cannot open fully at 10 V (or 0 V), which shifts the balance slightly
    null, dead = rows[:, VALVE_COLUMNS.index("null_v")], rows[:, VALVE_COLUMNS.index("deadband_v")]
    assert np.all(np.abs(lin.null_v - null) <= dead + 0.05)
    assert lin.null_v[0] == pytest.approx(5.0, abs=0.01)  # a symmetric valve: exactly its null
    # the dead band is jumped: just above 5 V each valve opens to supply
    v = lin(np.full(3, 5.05))
    a_s, _ = true_areas(rows, v)
    assert np.all(np.diag(a_s) > rows[:, VALVE_COLUMNS.index("null_leak_fraction")] * rows[:, 6])


def test_transform_from_the_calibration_inverts_the_real_valves(synthetic):
    rows, _, cal = synthetic
    lin = ValveLinearizer.from_calibration(cal)
    ideal = ValveLinearizer.from_valve_rows(rows)
    for uk in (1.0, 3.0, 7.0, 9.0):
        assert np.allclose(lin(np.full(3, uk)), ideal(np.full(3, uk)), atol=0.2)
    with pytest.raises(PneumasimError, match="expected 3"):
        lin(np.full(4, 5.0))


def test_fast_scenario_writes_metrics_and_plot(tmp_path):
    from scenarios.common import run_scenario

    m = run_scenario("arm2_orifice_calibration", tmp_path, fast=True, quiet=True)
    assert m["area_rel_error_median"] < 0.03 and m["area_rel_error_median_anchored"] < 0.03
    assert m["closed_area_abs_error_median_frac"] < 0.01
    assert (tmp_path / "orifice_calibration.png").stat().st_size > 10_000
