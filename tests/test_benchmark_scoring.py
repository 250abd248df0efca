"""The benchmarks' scoring: the confusion matrix every doctor benchmark draws."""
import numpy as np

from scenarios._benchmark import confusion_matrix

FAMS = ["coulomb_friction", "valve_lag", "heat_transfer", "none"]
COLS = FAMS + ["other"]


def _mat(*rows):
    return confusion_matrix([{"families": f, "named": n} for f, n in rows], FAMS, COLS)


def test_a_case_without_extra_findings_adds_one_count_per_hidden_family():
    rows = [(["coulomb_friction", "valve_lag"], ["heat_transfer"]), (["none"], []), (["valve_lag"], []),
            (["heat_transfer"], ["backlash", "valve_lag"]), (["coulomb_friction", "valve_lag"], ["valve_lag"])]
    for row in rows:
        assert np.isclose(_mat(row).sum(), len(row[0]))


def test_hits_go_on_the_diagonal_and_an_extra_finding_shows_in_the_hit_row():
    mat = _mat((["coulomb_friction"], ["coulomb_friction", "valve_lag"]))
    assert mat[0, COLS.index("coulomb_friction")] == 1 and mat[0, COLS.index("valve_lag")] == 1


def test_a_miss_shares_the_wrong_names_and_unknown_names_go_to_other():
    mat = _mat((["heat_transfer"], ["backlash", "valve_lag"]))
    assert mat[FAMS.index("heat_transfer"), COLS.index("valve_lag")] == 0.5
    assert mat[FAMS.index("heat_transfer"), COLS.index("other")] == 0.5


def test_nothing_named_is_the_none_column_and_a_clean_null_is_diagonal():
    mat = _mat((["valve_lag"], []), (["none"], []))
    assert mat[FAMS.index("valve_lag"), COLS.index("none")] == 1
    assert mat[FAMS.index("none"), COLS.index("none")] == 1


def test_same_decides_what_counts_as_a_hit():
    rows = [{"families": ["coulomb_friction"], "named": ["stiction"]}]
    mat = confusion_matrix(rows, FAMS, COLS + ["stiction"], same=lambda n, t: {n, t} <= {"coulomb_friction", "stiction"})
    assert mat[0, -1] == 1 and mat.sum() == 1
