"""Physics of the independent variant arm2 simulator (scenarios/_variantsim) and its effects."""
from __future__ import annotations

import math

import numpy as np
import pytest

from scenarios._variantsim import kernel as K
from scenarios._variantsim.arm import COLUMNS, Arm2Config
from scenarios._variantsim.control import record
from scenarios._variantsim.effects import FORMS, hidden_for
from scenarios._variantsim.hysteresis import BoucWen

ZERO2 = np.zeros(2)


def chamber_run(u, seconds, P=None, p0=4e5, q=0.0, qd=0.0, S=None):
    """Step the kernel with the links held at q (rad) moving at qd (rad/s, both joints);
    returns the state matrix and the pressure trace (steps, 4)."""
    P = Arm2Config().param_matrix() if P is None else P
    if S is None:
        S = np.zeros((K.NS, 4))
        S[K.SP] = S[K.SPT] = p0
        S[K.ST], S[K.SY], S[K.SPS, 0] = K.T0, 5.0, K.P_SUPPLY
    tau, trace = np.zeros(2), []
    qq = np.full(2, q)
    for i in range(round(seconds / 1e-3)):
        K.step_ms(np.full(4, float(u)), qq, np.full(2, qd), ZERO2, P, S, 1e-3, 4, tau)
        qq += qd * 1e-3
        trace.append(S[K.SP].copy())
    return S, np.array(trace)


def closed(P):
    P[K.AS] = P[K.AE] = 0.0
    return P


def volumes(P, q):
    x = 0.5 * P[K.STROKE, :2] + P[K.R_ARM, :2] * q
    return P[K.VD] + P[K.ACYL] * np.array([x[0], P[K.STROKE, 0] - x[0], x[1], P[K.STROKE, 1] - x[1]])


def test_closed_chamber_keeps_its_air():
    P = closed(Arm2Config().param_matrix())
    _, tr = chamber_run(5.0, 0.5, P)
    assert np.allclose(tr[-1], 4e5)                    # static: nothing flows, nothing changes
    _, tr = chamber_run(5.0, 0.3, P, qd=1.0)           # moving piston, no flow: p V^k constant (eq. 9)
    v0, v1 = volumes(P, 0.0), volumes(P, 0.3)
    assert np.allclose(4e5 * v0 ** K.KAPPA, tr[-1] * v1 ** K.KAPPA, rtol=2e-3)
    assert tr[-1, 0] < 4e5 < tr[-1, 1]                 # a expands, b is compressed


@pytest.mark.parametrize("u, bar", [(4.5, 1.5), (5.0, 5.3), (5.5, 6.9)])
def test_static_chamber_asymptotes_match_arm2_reference(u, bar):
    _, tr = chamber_run(u, 6.0, p0=1e5)
    assert tr[-1, 0] / 1e5 == pytest.approx(bar, abs=0.15)


def test_pidf_tracks_a_varied_reference_at_a_few_degrees():
    rec = record(Arm2Config(), None, 15.0, ref_seed=3, noise_seed=4)
    rms = np.degrees(np.sqrt(((rec["ref"] - rec["q_clean"]) ** 2).mean(0)))
    assert np.all(rms < 4.0) and np.ptp(np.degrees(rec["ref"]), axis=0).min() > 20
    assert np.all((rec["u"] >= 0) & (rec["u"] <= 10))
    assert np.allclose(rec["u"][:, 0] + rec["u"][:, 1], 10.0)   # antagonistic around 5 V, unclipped here


def test_laminar_external_leak_is_linear_in_p_squared_and_stops_at_room():
    P = closed(Arm2Config().param_matrix())
    P[K.EX_MODE, 0], P[K.EX_A, 0] = 1, 1e-16
    rates = []
    for p0 in (3e5, 6e5, 1e5):
        _, tr = chamber_run(5.0, 0.002, P, p0=p0)
        rates.append((tr[0, 0] - p0) / 1e-3)
    assert rates[0] < 0 and rates[1] < 0 and rates[2] == pytest.approx(0.0, abs=1e-6)
    assert rates[1] / rates[0] == pytest.approx((6e5**2 - 1e10) / (3e5**2 - 1e10), rel=2e-2)


def test_laminar_piston_leak_conserves_the_cylinders_air_and_equalises():
    P = closed(Arm2Config().param_matrix())
    P[K.PL_MODE, 0], P[K.PL_A, 0] = 1, 1e-16
    S = np.zeros((K.NS, 4))
    S[K.SP] = [6e5, 2e5, 4e5, 4e5]
    S[K.ST], S[K.SY], S[K.SPS, 0] = K.T0, 5.0, K.P_SUPPLY
    v = volumes(P, 0.0)
    before = (S[K.SP] * v)[:2].sum()
    S, tr = chamber_run(5.0, 1.0, P, S=S)
    assert (tr[-1] * v)[:2].sum() == pytest.approx(before, rel=1e-9)      # mass = p V / (k R T), eq. 9
    assert abs(tr[-1, 0] - tr[-1, 1]) < 0.5 * 4e5 and tr[-1, 0] > tr[-1, 1]


def test_underlap_leak_only_inside_its_band_and_balances_midway():
    P = closed(Arm2Config().param_matrix())
    P[K.VL_MODE, 0], P[K.VL_A, 0], P[K.VL_W, 0] = 1, 2e-10, 0.15
    _, tr = chamber_run(5.0, 3.0, P, p0=1e5)
    assert tr[-1, 0] == pytest.approx((K.P_SUPPLY + K.P_ATM) / 2, rel=1e-3)   # equal conductances both ways
    _, tr = chamber_run(5.0 + 5 * 0.16, 0.5, P, p0=1e5)                      # outside the band
    assert tr[-1, 0] == pytest.approx(1e5)


def test_bouc_wen_hysteresis_is_bounded_and_lags_the_command():
    op = BoucWen(0.3)
    op.reset(5.0)
    spool_up = [op(u) for u in np.linspace(5, 8, 61)]
    assert abs(op.z) <= 0.3 + 1e-12 and 8 - spool_up[-1] == pytest.approx(0.3, abs=0.01)
    spool_dn = [op(u) for u in np.linspace(8, 7.8, 5)]
    assert np.ptp(spool_dn) < 1e-9          # on reversal the spool waits: z shrinks with the command


def test_second_order_spool_overshoots_as_its_damping_ratio_says():
    P = Arm2Config().param_matrix()
    zeta = 0.5
    P[K.SP_W, 0], P[K.SP_Z, 0] = 2 * math.pi * 10, zeta
    S = np.zeros((K.NS, 4))
    S[K.SP], S[K.ST], S[K.SY], S[K.SPS, 0] = 4e5, K.T0, 5.0, K.P_SUPPLY
    ys, tau = [], np.zeros(2)
    for _ in range(300):
        K.step_ms(np.full(4, 6.0), ZERO2, ZERO2, ZERO2, P, S, 1e-3, 4, tau)
        ys.append(S[K.SY, 0])
    overshoot = (max(ys) - 6.0) / 1.0
    assert overshoot == pytest.approx(math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)), abs=0.03)
    assert ys[-1] == pytest.approx(6.0, abs=1e-3)


def friction_torque(row_values, v, steps=400):
    """Friction torque on joint 0 at constant rate v [rad/s], pressures equal."""
    P = closed(Arm2Config().param_matrix())
    for row, val in row_values.items():
        P[row, 0] = val
    P0 = closed(Arm2Config().param_matrix())
    out = []
    for PP in (P, P0):
        S = np.zeros((K.NS, 4))
        S[K.SP], S[K.ST], S[K.SY], S[K.SPS, 0] = 4e5, K.T0, 5.0, K.P_SUPPLY
        tau = np.zeros(2)
        for _ in range(steps):
            K.step_ms(np.full(4, 5.0), ZERO2, np.array([v, 0.0]), ZERO2, PP, S, 1e-3, 1, tau)
            S[K.SP] = 4e5
        out.append(tau[0])
    return out[1] - out[0]


def test_lugre_steady_friction_follows_the_stribeck_curve_and_opposes_motion():
    lugre = {K.LG_FC: 0.1, K.LG_FS: 0.15, K.LG_VS: 0.05, K.LG_S0: 1000.0, K.LG_S1: 1.5, K.LG_S2: 0.0}
    for v in (0.02, 0.2, -0.5):
        expect = 0.1 + 0.05 * math.exp(-(v / 0.05) ** 2)
        assert friction_torque(lugre, v) == pytest.approx(math.copysign(expect, v), rel=1e-3)


def test_karnopp_sticks_below_breakaway_and_slides_at_coulomb():
    karnopp = {K.KP_FS: 0.5, K.KP_FC: 0.2, K.KP_DV: 0.02}
    assert friction_torque(karnopp, 0.5, steps=1) == pytest.approx(0.2)
    P = closed(Arm2Config().param_matrix())
    P[K.KP_FS, 0], P[K.KP_FC, 0], P[K.KP_DV, 0] = 0.5, 0.2, 0.02
    S = np.zeros((K.NS, 4))
    aa, ab, r = P[K.ACYL, 0], P[K.ACYL, 1], P[K.R_ARM, 0]
    for torque, held in ((0.3, 0.0), (0.8, 0.3)):        # below breakaway: held; above: slips at Fs
        pa = (torque / r + ab * 4e5 + (aa - ab) * K.P_ATM) / aa
        S[K.SP], S[K.ST], S[K.SPS, 0] = [pa, 4e5, 4e5, 4e5], K.T0, K.P_SUPPLY
        tau = np.zeros(2)
        K.step_ms(np.full(4, 5.0), ZERO2, ZERO2, ZERO2, P, S, 1e-3, 1, tau)
        assert tau[0] == pytest.approx(held, abs=1e-3)


def test_viscous_seal_term_grows_with_mean_pressure():
    f4 = friction_torque({K.VS_B0: 0.05, K.VS_B1: 1e-7}, 0.5, steps=1)
    assert f4 == pytest.approx((0.05 + 1e-7 * 3e5) * 0.5, rel=1e-3)   # mean pressure 4 bar
    assert friction_torque({K.VS_B0: 0.05, K.VS_B1: 1e-7}, -0.5, steps=1) == pytest.approx(-f4, rel=1e-3)


def test_compliant_backlash_transmits_nothing_inside_the_gap_and_settles_on_contact():
    P = closed(Arm2Config().param_matrix())
    P[K.BL_GAP, 0], P[K.BL_K, 0], P[K.BL_C, 0] = 0.02, 30.0, 0.05
    S = np.zeros((K.NS, 4))
    S[K.SP], S[K.ST], S[K.SPS, 0] = [4e5, 4e5, 4e5, 4e5], K.T0, K.P_SUPPLY
    tau = np.zeros(2)
    S[K.SP, :2] = [K.P_ATM * 1.0, K.P_ATM * 1.0]
    P[K.ACYL, 1] = P[K.ACYL, 0]                            # equal areas: no cylinder torque
    K.step_ms(np.full(4, 5.0), ZERO2, ZERO2, ZERO2, P, S, 1e-3, 4, tau)
    assert tau[0] == 0.0
    S[K.STH, 0] = 0.03                                     # piston 0.02 rad past the gap's edge
    K.step_ms(np.full(4, 5.0), ZERO2, ZERO2, ZERO2, P, S, 1e-3, 4, tau)
    assert 0 < tau[0] <= 30.0 * 0.02 + 1e-9


def test_regulator_reservoir_holds_supply_at_no_demand_and_droops_under_flow():
    P = Arm2Config().param_matrix()
    P[K.SU_MODE, 0], P[K.SU_A, 0], P[K.SU_V, 0] = K.SU_RESERVOIR, 0.6e-6, 3e-5
    S, _ = chamber_run(5.0, 0.5, closed(P.copy()), p0=5.3e5)
    idle = S[K.SPS, 0]
    S, _ = chamber_run(10.0, 0.02, P, p0=1e5)
    assert idle == pytest.approx(K.P_SUPPLY, rel=2e-3) and S[K.SPS, 0] < 0.9 * K.P_SUPPLY


def test_strong_heat_transfer_makes_compression_isothermal():
    P = closed(Arm2Config().param_matrix())
    P[K.HT_NAT, 0], P[K.HT_F, 0], P[K.HT_SCALE, 0] = 50.0, 0.0, 1.0    # wall contact far faster than the motion
    _, tr = chamber_run(5.0, 0.3, P, qd=-1.0)                       # chamber a compressed
    v0, v1 = volumes(P, 0.0)[0], volumes(P, -0.3)[0]
    assert tr[-1, 0] == pytest.approx(4e5 * v0 / v1, rel=0.02)     # p V = const, not p V^1.4


def test_line_dynamics_chamber_lags_its_tube():
    P = Arm2Config().param_matrix()
    P[K.LN_MODE, 0], P[K.LN_V, 0], P[K.LN_TAU, 0] = K.LN_TWO_VOLUME, 2e-6, 0.02
    S, tr = chamber_run(8.0, 0.01, P, p0=2e5)
    assert S[K.SPT, 0] > tr[-1, 0] > 2e5
    pv = S[K.SP, 0] * volumes(P, 0.0)[0] + S[K.SPT, 0] * 2e-6
    S, tr = chamber_run(5.0, 0.5, closed(P), S=S)                  # valve shut: the two volumes equalise
    assert S[K.SPT, 0] == pytest.approx(tr[-1, 0], rel=1e-6)
    assert S[K.SP, 0] * volumes(P, 0.0)[0] + S[K.SPT, 0] * 2e-6 == pytest.approx(pv, rel=1e-9)   # air kept


@pytest.mark.parametrize("u", [0.0, 10.0, 5.3])
def test_a_tiny_concealed_tube_stays_finite_and_fills_towards_its_source(u):
    """A two-volume line shrunk by concealment (0.1 cm^3, 1 ms): the valve relaxes it at
    ~1e5 1/s, far faster than one 0.25 ms fluid step; in sub-steps it stays finite and between
    room and supply pressure, and the chamber fills and empties through it."""
    P = Arm2Config().param_matrix()
    P[K.LN_MODE, 0], P[K.LN_V, 0], P[K.LN_TAU, 0] = K.LN_TWO_VOLUME, 1e-7, 0.001
    S, tr = chamber_run(u, 0.5, P, p0=3e5)
    assert np.all(np.isfinite(tr)) and np.isfinite(S[K.SPT, 0])
    assert K.P_ATM * 0.99 < S[K.SPT, 0] < K.P_SUPPLY * 1.01
    if u == 10.0:
        assert tr[-1, 0] > 0.9 * K.P_SUPPLY and abs(S[K.SPT, 0] - tr[-1, 0]) < 0.02 * K.P_SUPPLY
    if u == 0.0:
        assert tr[-1, 0] < 0.5 * 3e5          # exhausting through the tube: fallen by more than half


def test_every_form_applies_and_scale_shrinks_magnitudes():
    rng = np.random.default_rng(0)
    for fam, forms in FORMS.items():
        for form in forms:
            place = {"joint": "elbow", "chamber": "elbow.b", "actuator": "elbow", "supply": "all"}[form.kind]
            params = form.draw(rng, {"place": place})
            half = form.effective(params, 0.5)
            h = hidden_for([{"family": fam, "form": form.name, "place": place, "parameters": params}], 0.5)
            changed = (any(h.P_rows.values()) or h.hysteresis or h.dead_time_s.any() or h.pressure_offset_pa.any()
                       or h.angle_offset_rad.any())
            assert changed, (fam, form.name)
            assert half != params, (fam, form.name)


def test_make_case_writes_readable_recordings_and_truth(tmp_path):
    from pneumatics.recording import read_csv
    from scenarios._variantsim.cases import make_case

    truth = make_case(tmp_path, 11, ["external_leak"], seconds=3.0, heldout_seconds=2.0)
    rec = read_csv(truth["recordings"]["main"])
    assert set(COLUMNS[1:]) <= set(rec.columns)
    assert len(rec.time) == 300 and truth["effects"][0]["scale"] == truth["concealment"]["scale"]
    assert set(truth["concealment"]["r2_per_channel"]) == set(COLUMNS[1:7])
    # the same visibility measure on the held-out recording: an external leak acts all the time
    seen = truth["heldout_visibility"]
    assert set(seen["r2_per_channel"]) == set(COLUMNS[1:7]) and seen["regime_fraction"] > 0.5
    assert (tmp_path / "variant_11.truth.json").exists()


def test_unknown_family_is_a_clear_error(tmp_path):
    from scenarios._variantsim.cases import make_case

    with pytest.raises(ValueError, match="unknown effect family 'valve_leek'"):
        make_case(tmp_path, 1, ["valve_leek"], seconds=1.0, heldout_seconds=1.0)


def test_variant_benchmark_fast(tmp_path, monkeypatch):
    """The --fast variant benchmark (a null case, LuGre friction, Bouc-Wen hysteresis; 30 s +
    15 s each) in this process: nothing found on the null, both effects named and placed
    (seen: 3/3, ~50-80 s)."""
    from scenarios.common import run_scenario

    monkeypatch.setenv("PNEUMASIM_BACKEND", "inline")
    m = run_scenario("doctor_variant_benchmark", tmp_path, fast=True, quiet=True)
    assert m["cases"] == 3
    assert m["null_false_discovery_rate"] == 0.0
    assert m["effect_accuracy"] >= 0.5 and m["location_accuracy"] >= 0.5
    assert (tmp_path / "confusion_matrix.png").is_file()


def test_a_pairs_effects_are_each_concealed_at_their_own_scale(tmp_path):
    """Each effect of a pair is concealed alone first, then both at a common multiple of those
    scales: a strong end stop does not push a line beside it to a scale no sensor resolves."""
    from scenarios._variantsim.cases import make_case
    truth = make_case(tmp_path, 488402088, ["end_stop", "line_dynamics"], forms=["hunt_crossley_bumper", "delay_plus_volume"],
                      seconds=20.0, heldout_seconds=2.0, name="pair")
    stop, line = truth["effects"]
    c = truth["concealment"]
    assert c["effect_scales"] == [stop["scale"], line["scale"]] and line["scale"] > 4 * stop["scale"]
    assert c["scale"] <= 1.0 and c["min_r2"] >= 0.9
