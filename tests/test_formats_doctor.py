"""The doctor reads a Parquet file and an MCAP bag made from a CSV recording exactly as it reads
the CSV: the same Recordings (fast), and the same report.json (slow, through the CLI)."""
import json
from pathlib import Path

import numpy as np
import pytest

from identification.doctor.valve_arm.data import prepare
from pneumasim.cli import build_parser, recordings_from_args
from pneumasim.cli import main as cli_main
from pneumatics.formats.by_suffix import read_recording, write_recording
from pneumatics.recording import read_csv

from test_formats_parquet import arm2_like
from test_formats_rosbag import with_reference

BLIND = Path(__file__).resolve().parents[2] / "shared" / "samples" / "arm2-blind"
CASE = "case_befd9d0f"  # LuGre friction on the shoulder (blind sample)


def three_formats(tmp_path, seconds=None):
    """As CSV, and the Parquet file and MCAP bag made from that CSV: {format: [recording,
    held-out]}: the first ``seconds`` (and half as much held out) of a blind case, or without
    ``seconds`` a synthetic arm2 recording of 3 s (and 1.5 s)."""
    files = {}
    for part, cut in (("", seconds), ("_heldout", seconds / 2 if seconds else None)):
        if seconds:
            read_csv(BLIND / f"{CASE}{part}.csv").slice(0, cut).to_csv(tmp_path / f"run{part}.csv")
        else:
            with_reference(arm2_like(n=300 if part == "" else 150)).to_csv(tmp_path / f"run{part}.csv")
        rec = read_csv(tmp_path / f"run{part}.csv")
        files.setdefault("csv", []).append(tmp_path / f"run{part}.csv")
        files.setdefault("parquet", []).append(write_recording(rec, tmp_path / f"run{part}.parquet"))
        files.setdefault("mcap", []).append(write_recording(rec, tmp_path / f"run{part}.mcap", "ros_arm2")
                                            / f"run{part}.mcap")
    return files


def doctor_args(files, out):
    return ["doctor", "--model", "arm2", str(files[0]), "--holdout", str(files[1]), "--map", "ros_arm2",
            "--out", str(out)]


def test_the_doctor_reads_the_same_recordings_from_csv_parquet_and_mcap(tmp_path, arm2):
    files = three_formats(tmp_path)
    read = {fmt: recordings_from_args(build_parser().parse_args(doctor_args(f, tmp_path / fmt)))
            for fmt, f in files.items()}
    for fmt in ("parquet", "mcap"):
        for rec, ref in zip([*read[fmt][0], *read[fmt][1]], [*read["csv"][0], *read["csv"][1]]):
            assert list(rec.columns) == list(ref.columns), fmt
            np.testing.assert_array_equal(rec.time, ref.time)
            for name in ref.columns:
                np.testing.assert_array_equal(rec[name], ref[name], err_msg=f"{fmt} {name}")
            assert rec.meta.get("daq_averaging", True) is ref.meta.get("daq_averaging", True)
            assert rec.meta.get("model") in (None, "arm2")
    # what the doctor computes from them first: validated, smoothed, differentiated, placed in time
    a, b, c = (prepare(arm2, read[fmt][0][0]) for fmt in ("csv", "parquet", "mcap"))
    for name in ("t", "t_sensor", "q_s", "qd", "p", "u"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)
        np.testing.assert_array_equal(getattr(c, name), getattr(a, name), err_msg=name)


def test_a_folder_bag_is_read_by_the_doctor_with_its_map(tmp_path):
    files = three_formats(tmp_path)
    folder = files["mcap"][0].parent
    args = build_parser().parse_args(doctor_args([folder, files["csv"][1]], tmp_path / "x"))
    recs, holds = recordings_from_args(args)
    np.testing.assert_array_equal(recs[0]["p_a.elbow"], read_recording(files["csv"][0])["p_a.elbow"])


RUN_DEPENDENT = ("seconds", "train_sources", "heldout_sources")  # wall time and file names


@pytest.mark.slow
@pytest.mark.skipif(not BLIND.is_dir(), reason="shared/samples not beside the repo")
def test_parquet_and_mcap_give_the_doctor_report_of_the_csv(tmp_path):
    """10 s fitted and 5 s held out of a blind case; ~45-50 s for the three doctor runs."""
    files = three_formats(tmp_path, seconds=10.0)
    reports = {}
    for fmt, f in files.items():
        cli_main(doctor_args(f, tmp_path / fmt))
        reports[fmt] = json.loads((tmp_path / fmt / "report.json").read_text())
        for key in RUN_DEPENDENT:
            reports[fmt]["diagnostics"].pop(key)
    assert reports["csv"]["findings"], "the short case should still name its friction"
    assert reports["parquet"] == reports["csv"]
    assert reports["mcap"] == reports["csv"]
