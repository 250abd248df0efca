"""The variant simulator's form registry (scenarios/_variantsim, "variantsim-6"): every form of
every family makes a case that moves the channels its place says, piston leaks keep the
cylinder's air, a two-sided end stop pushes back on both sides, and the simulator stays
independent of pneumasim."""
from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest

from scenarios._variantsim import kernel as K
from scenarios._variantsim.arm import ANGLE_NOISE_RAD, COLUMNS, PRESSURE_NOISE_PA, Arm2Config
from scenarios._variantsim.cases import make_case
from scenarios._variantsim.forms import FAMILIES, FORMS, OUTSIDE, forms_table
from scenarios._variantsim.hysteresis import BoucWen, JilesAtherton, Play, Preisach

ROOT = Path(__file__).resolve().parents[1]
SEED = 21
ALL_FORMS = [(fam, f.name) for fam, forms in FORMS.items() for f in forms]


def _load(truth) -> np.ndarray:
    return np.loadtxt(truth["recordings"]["main"], delimiter=",", skiprows=1)


@pytest.fixture(scope="module")
def null_twin(tmp_path_factory):
    """The same seed's case without effects (same perturbed arm, reference and noise)."""
    out = tmp_path_factory.mktemp("null")
    return _load(make_case(out, SEED, [], seconds=4.0, heldout_seconds=1.0, fraction=0.03, conceal_effects=False))


def expected_columns(effect: dict) -> list[str]:
    """The recorded channels a form at this place must move."""
    kind, place = effect["place_kind"], effect["place"]
    if kind == "chamber":
        joint, ch = place.split(".")
        return [f"p_{ch}.{joint}"]
    if kind == "actuator":
        return [f"p_a.{place}", f"p_b.{place}"]
    if kind == "supply":
        return [c for c in COLUMNS if c.startswith("p_")]
    return [f"q.{place}"]


@pytest.mark.parametrize("family, form", ALL_FORMS, ids=[f"{a}/{b}" for a, b in ALL_FORMS])
def test_every_form_makes_a_case_that_moves_its_channels(family, form, null_twin, tmp_path):
    truth = make_case(tmp_path, SEED, [family], forms=[form], seconds=4.0, heldout_seconds=1.0, fraction=0.03,
                      conceal_effects=False)
    eff = truth["effects"][0]
    assert truth["generator"] == "variantsim-6" and eff["form"] == eff["kind"] == form and eff["source"]
    table = _load(truth)
    assert np.isfinite(table).all() and table.shape == null_twin.shape
    diff = np.abs(table - null_twin).max(0)
    for col in expected_columns(eff):
        i = COLUMNS.index(col)
        noise = ANGLE_NOISE_RAD if col.startswith("q.") else PRESSURE_NOISE_PA
        assert diff[i] > 3 * noise, f"{family}/{form} at {eff['place']}: {col} moved {diff[i]:.3g}"
    assert json.loads(Path(truth["recordings"]["main"]).with_name(f"{truth['case_id']}.truth.json").read_text())


def test_registry_has_three_forms_per_family_and_two_outside_per_place_kind():
    assert "force_sensor_offset" not in FORMS and "end_stop" in FAMILIES and OUTSIDE not in FAMILIES
    assert all(len(FORMS[f]) >= 3 for f in FAMILIES)
    kinds = [f.kind for f in FORMS[OUTSIDE]]
    assert all(kinds.count(k) >= 2 for k in ("chamber", "joint", "supply"))
    assert all(f.source and f.summary for forms in FORMS.values() for f in forms)


def test_a_pair_of_interacting_effects_takes_both_and_bad_forms_are_clear_errors(tmp_path):
    truth = make_case(tmp_path, 5, ["supply_droop", "valve_leak"], forms=["static_droop", None], seconds=2.0,
                      heldout_seconds=1.0, conceal_effects=False)
    assert [e["family"] for e in truth["effects"]] == ["supply_droop", "valve_leak"]
    assert truth["effects"][0]["where"] == {"supply": "all"} and "chamber" in truth["effects"][1]["where"]
    with pytest.raises(ValueError, match="has no form 'lugre'"):
        make_case(tmp_path, 1, ["stiction"], forms=["lugre"], seconds=1.0, heldout_seconds=1.0)
    with pytest.raises(ValueError, match="one form name"):
        make_case(tmp_path, 1, ["stiction"], forms=[None, None], seconds=1.0, heldout_seconds=1.0)


def closed_cylinder(mode, a, b=0.0):
    P = Arm2Config().param_matrix()
    P[K.AS] = P[K.AE] = 0.0
    P[K.PL_MODE, 0], P[K.PL_A, 0], P[K.PL_B, 0] = mode, a, b
    S = np.zeros((K.NS, 4))
    S[K.SP] = [6e5, 2e5, 4e5, 4e5]
    S[K.ST], S[K.SY], S[K.SPS, 0] = K.T0, 5.0, K.P_SUPPLY
    return P, S


@pytest.mark.parametrize("mode, a, b", [(1, 1e-16, 0.0), (2, 2e-8, 0.0), (3, 4e-11, 0.3)])
def test_piston_leak_keeps_a_closed_cylinders_air(mode, a, b):
    P, S = closed_cylinder(mode, a, b)
    x = 0.5 * P[K.STROKE, 0]
    vol = P[K.VD, :2] + P[K.ACYL, :2] * x
    before = (S[K.SP, :2] * vol).sum()            # mass = p V / (kappa R T0) in paper 002 eq. 9
    tau = np.zeros(2)
    for _ in range(500):
        K.step_ms(np.full(4, 5.0), np.zeros(2), np.zeros(2), np.zeros(2), P, S, 1e-3, 4, tau)
    assert (S[K.SP, :2] * vol).sum() == pytest.approx(before, rel=1e-9)
    assert 2e5 < S[K.SP, 1] < S[K.SP, 0] < 6e5      # flowed from a to b, not past equal


@pytest.mark.parametrize("mode", [1, 2, 3])
def test_two_sided_end_stop_pushes_back_on_both_sides(mode):
    P = Arm2Config().param_matrix()
    P[K.AS] = P[K.AE] = 0.0
    P[K.ES_MODE, 1], P[K.ES_HI, 1], P[K.ES_LO, 1] = mode, 0.4, -0.3
    P[K.ES_K, 1], P[K.ES_C, 1], P[K.ES_N, 1], P[K.ES_K3, 1] = 200.0, 1.0, 1.5, 1e4
    torques = {}
    for q in (-0.35, 0.0, 0.45):
        S = np.zeros((K.NS, 4))
        S[K.SP], S[K.ST], S[K.SY], S[K.SPS, 0] = 4e5, K.T0, 5.0, K.P_SUPPLY
        P_off = P.copy()
        P_off[K.ES_MODE, 1] = 0.0
        tau, tau_off = np.zeros(2), np.zeros(2)
        K.step_ms(np.full(4, 5.0), np.array([0.0, q]), np.zeros(2), np.zeros(2), P, S.copy(), 1e-3, 4, tau)
        K.step_ms(np.full(4, 5.0), np.array([0.0, q]), np.zeros(2), np.zeros(2), P_off, S.copy(), 1e-3, 4, tau_off)
        torques[q] = tau[1] - tau_off[1]
    assert torques[-0.35] > 0 and torques[0.45] < 0 and torques[0.0] == 0.0
    if mode == 1:
        assert torques[0.45] == pytest.approx(-200.0 * 0.05) and torques[-0.35] == pytest.approx(200.0 * 0.05)


FORBIDDEN = {"pneumatics", "identification", "controllers", "models"}


def test_the_variant_simulator_imports_nothing_of_pneumasim():
    for path in sorted((ROOT / "scenarios" / "_variantsim").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            elif isinstance(node, ast.ImportFrom) and node.level > 1:
                names = ["<outside the package>"]
            for n in names:
                assert n.split(".")[0] not in FORBIDDEN | {"scenarios", "<outside the package>"}, f"{path.name}: {n}"


def test_the_docs_table_is_the_registrys():
    text = (ROOT / "docs" / "effects_variants.md").read_text()
    assert forms_table() in text


@pytest.mark.parametrize("op", [Play(0.3), BoucWen(0.3), Preisach(0.3, 0.5, 1), JilesAtherton(0.3, 0.2, 15.0, 0.01)],
                         ids=["play", "bouc_wen", "preisach", "jiles_atherton"])
def test_valve_hysteresis_operators_trail_the_command_both_ways(op):
    op.reset(3.0)
    up = np.linspace(3.0, 7.0, 81)
    spool_up = np.array([op(u) for u in up])
    spool_dn = np.array([op(u) for u in up[::-1]])[::-1]
    mid = 40                                           # u = 5 V on both branches
    assert spool_up[mid] < 5.0 - 0.15 and spool_dn[mid] > 5.0 + 0.15      # a loop around the command
    assert np.abs(spool_up - up).max() < 0.3 * 1.5 + 0.05                 # bounded by its width (+ spread)


def test_compressor_cycles_between_its_switch_pressures():
    P = Arm2Config().param_matrix()
    P[K.AS] = P[K.AE] = 0.0                            # no valve demand: the system leak drains it
    P[K.SU_MODE, 0], P[K.SU_V, 0], P[K.SU_QC, 0], P[K.SU_BAND, 0], P[K.SU_LK, 0] = K.SU_COMPRESSOR, 5e-4, 3e-4, 3e4, 5e-11
    S = np.zeros((K.NS, 4))
    S[K.SP], S[K.ST], S[K.SY], S[K.SPS, 0] = 4e5, K.T0, 5.0, K.P_SUPPLY
    trace, tau = [], np.zeros(2)
    for _ in range(15000):
        K.step_ms(np.full(4, 5.0), np.zeros(2), np.zeros(2), np.zeros(2), P, S, 1e-3, 4, tau)
        trace.append(S[K.SPS, 0])
    trace = np.array(trace)
    assert trace.min() == pytest.approx(K.P_SUPPLY - 3e4, abs=200) and trace.max() == pytest.approx(K.P_SUPPLY, abs=200)
    filling = np.diff(trace) > 0
    assert np.sum(filling[1:] & ~filling[:-1]) >= 2       # the compressor started at least twice in 15 s


@pytest.mark.parametrize("form", ["compliant_dead_zone", "rigid_dead_zone", "impact_damped_dead_zone"])
def test_every_dead_zone_is_stable_on_the_elbows_lighter_piston(form, tmp_path):
    """At the elbow (piston 3.8e-5 kg m^2, the lighter one) every contact must stay stable at the
    0.25 ms step (the rigid form at zeta 0.7 gave NaN).  The seed: the first whose draw puts the
    form at the elbow (make_case draws with default_rng(seed))."""
    from scenarios._variantsim.cases import draw_effects

    seed = next(s for s in range(100)
                if draw_effects(np.random.default_rng(s), ["backlash"], [form])[0]["where"] == {"joint": "elbow"})
    truth = make_case(tmp_path, seed, ["backlash"], forms=[form], seconds=4.0, heldout_seconds=1.0,
                      conceal_effects=False)
    assert truth["effects"][0]["where"] == {"joint": "elbow"}
    assert np.isfinite(_load(truth)).all()


def test_a_recording_that_is_not_finite_fails_in_the_case_maker(tmp_path, monkeypatch):
    """An unstable form must fail where it is made, naming the case and columns, rather than
    leave a NaN recording for the doctor to refuse."""
    import scenarios._variantsim.cases as cases

    real = cases.record

    def broken(*args, **kw):
        rec = real(*args, **kw)
        rec["p"][:, 2] = np.nan
        return rec
    monkeypatch.setattr(cases, "record", broken)
    with pytest.raises(ValueError, match=r"non-finite values in p_a\.elbow"):
        make_case(tmp_path, 1, [], seconds=1.0, heldout_seconds=1.0)


def test_stiction_holds_twice_its_sliding_level_and_coulomb_lugre_less_than_one_and_a_half():
    """The boundary between the two friction families is the torque the law can hold: a Stribeck
    curve is drawn again until it peaks at 2 F_c or more, the Coulomb family's LuGre breaks away
    at 1.1-1.4 F_c (forms_joint.STICTION_MIN_PEAK)."""
    from scenarios._variantsim.forms import form_of
    from scenarios._variantsim.forms_joint import STICTION_MIN_PEAK, stribeck_peak
    rng = np.random.default_rng(5)
    for _ in range(50):
        e = form_of("stiction", "stribeck_power").draw(rng, {})
        assert stribeck_peak(e) >= STICTION_MIN_PEAK and 2.0 <= e["fs_nm"] / e["fc_nm"] <= 3.5
        lugre = form_of("coulomb_friction", "lugre_friction").draw(rng, {})
        assert 1.1 <= lugre["fs_nm"] / lugre["fc_nm"] <= 1.4
    # a tanh as wide as the Stribeck velocity hides most of the breakaway
    wide = {"fc_nm": 0.05, "fs_nm": 0.139, "vs_rad_s": 0.022, "delta": 0.775, "ve_rad_s": 0.02}
    assert stribeck_peak(wide) == pytest.approx(1.36, abs=0.03)
    assert stribeck_peak({**wide, "delta": 2.0, "ve_rad_s": 1e-4}) == pytest.approx(0.139 / 0.05, rel=0.02)
