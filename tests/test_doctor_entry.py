"""The one doctor entry (identification.doctor): it dispatches on the model's kind, writes the
kind's report, and names the models it reads when given one without a doctor."""
import json

import pytest

from identification.doctor import diagnose, kind_of, summary, write
from pneumatics.errors import UnknownNameError
from test_bench_doctor import _cyl_rec


def test_kinds_of_the_shipped_models():
    assert kind_of("arm2") == "valve_arm" and kind_of("humanoid38") == "valve_arm"
    assert kind_of("jetpipe") == "jetpipe"
    assert kind_of("bench_chamber") == "bench" and kind_of("bench_cylinder") == "bench"
    assert kind_of("sarcos_elbow") == "hydraulic"


def test_a_model_without_a_doctor_is_refused_with_the_valid_names(monkeypatch):
    import models

    kind = models.model_kind
    monkeypatch.setattr(models, "model_kind", lambda m: "pneumatic_gripper" if m == "sarcos_elbow" else kind(m))
    with pytest.raises(UnknownNameError) as e:
        kind_of("sarcos_elbow")  # every shipped model has a doctor: a kind without one, pretended
    for name in ("arm2", "humanoid38", "jetpipe", "bench_chamber", "bench_cylinder"):
        assert name in str(e.value)


def test_bench_recording_through_the_entry_gives_the_bench_report(tmp_path):
    stages = []
    rep = diagnose("bench_cylinder", [_cyl_rec(3, 6.0, 0.0, duration=20.0)], progress=stages.append)
    assert stages and rep["model"] == "bench_cylinder"
    assert [f["effect"] for f in rep["findings"]] == ["coulomb_friction"]
    write(rep, tmp_path / "d")
    written = json.loads((tmp_path / "d" / "report.json").read_text())
    assert written["findings"][0]["effect"] == "coulomb_friction"
    assert "coulomb_friction" in summary(rep)
