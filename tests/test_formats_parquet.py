"""Recordings as Parquet: a lossless round trip, the metadata in the schema, and the CSV
reader's checks with the same messages (a CSV line is a Parquet row + 1)."""
import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from pneumatics.errors import RecordingError
from pneumatics.formats.by_suffix import read_recording
from pneumatics.formats.parquet import META_KEY
from pneumatics.recording import Recording, RecordingWarning, read_csv, read_parquet, validate

JOINTS, ACTS = ["shoulder", "elbow"], ["shoulder", "elbow"]


def arm2_like(n=300, rate_hz=100.0) -> Recording:
    """A recording with every arm2 channel: smooth angles, pressures around 4 bar abs, commands."""
    t = np.arange(n) / rate_hz
    cols = {}
    for k, j in enumerate(JOINTS):
        cols[f"q.{j}"] = 0.3 * np.sin(2 * np.pi * (0.4 + 0.2 * k) * t)
    for k, a in enumerate(ACTS):
        cols[f"p_a.{a}"] = 4.0e5 + 5e4 * np.sin(2 * np.pi * 0.7 * t + k)
        cols[f"p_b.{a}"] = 4.0e5 - 5e4 * np.sin(2 * np.pi * 0.7 * t + k)
    for k, a in enumerate(ACTS):
        cols[f"u_a.{a}"] = 5.0 + 2.0 * np.sign(np.sin(2 * np.pi * 0.5 * t + k))
        cols[f"u_b.{a}"] = 10.0 - cols[f"u_a.{a}"]
    return Recording(t, cols, {"model": "arm2", "seed": 3, "note": "synthetic"}, "<test>")


def test_round_trip_is_lossless_and_keeps_the_metadata(tmp_path):
    rec = arm2_like()
    rec.to_parquet(tmp_path / "r.parquet")
    assert not (tmp_path / "r.json").exists()  # the metadata lives in the file itself
    back = read_parquet(tmp_path / "r.parquet")
    assert list(back.columns) == list(rec.columns)
    np.testing.assert_array_equal(back.time, rec.time)
    for name in rec.columns:
        np.testing.assert_array_equal(back[name], rec[name])  # float64 both ways: bit for bit
    assert back.meta == rec.meta
    assert validate(back, JOINTS, ACTS, model_name="arm2") == []
    schema_meta = pq.read_schema(tmp_path / "r.parquet").metadata
    assert json.loads(schema_meta[META_KEY])["seed"] == 3


def test_writing_by_suffix_gives_the_same_recording_as_csv_and_parquet(tmp_path):
    rec = arm2_like()
    rec.write(tmp_path / "r.csv")
    rec.write(tmp_path / "r.parquet")
    a, b = read_recording(tmp_path / "r.csv"), read_recording(tmp_path / "r.parquet")
    assert a.meta == b.meta == rec.meta
    for name in rec.columns:
        np.testing.assert_allclose(a[name], b[name], rtol=1e-6)  # CSV keeps 7 digits
    with pytest.raises(RecordingError, match="cannot write a recording as '.txt'; valid: .csv, .parquet"):
        rec.write(tmp_path / "r.txt")


def _both(tmp_path, header, rows):
    """The same table as CSV and as Parquet; the errors of reading each."""
    (tmp_path / "r.csv").write_text(",".join(header) + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    data = np.array(rows, dtype=float)
    pq.write_table(pa.table({h: data[:, j] for j, h in enumerate(header)}), tmp_path / "r.parquet")
    errors = []
    for reader, name in ((read_csv, "r.csv"), (read_parquet, "r.parquet")):
        with pytest.raises(RecordingError) as e:
            reader(tmp_path / name)
        errors.append(str(e.value))
    return errors


HEADER = ["time", "q.shoulder", "p_a.shoulder"]


def test_nan_gets_the_csv_error(tmp_path):
    csv_err, pq_err = _both(tmp_path, HEADER, [[0.0, 0.1, 3e5], [0.01, float("nan"), 3e5], [0.02, 0.1, 3e5]])
    assert "line 3, column 'q.shoulder' is nan (1 non-finite value(s) in all)" in csv_err
    assert "row 2, column 'q.shoulder' is nan (1 non-finite value(s) in all)" in pq_err
    assert csv_err.split(": ", 1)[1].replace("line 3", "X") == pq_err.split(": ", 1)[1].replace("row 2", "X")


def test_time_going_back_gets_the_csv_error(tmp_path):
    csv_err, pq_err = _both(tmp_path, HEADER, [[0.0, 0.1, 3e5], [0.02, 0.1, 3e5], [0.01, 0.1, 3e5]])
    assert "time is not strictly increasing at line 4 (0.02 s then 0.01 s)" in csv_err
    assert "time is not strictly increasing at row 3 (0.02 s then 0.01 s)" in pq_err
    assert pq_err.startswith(str(tmp_path / "r.parquet"))


def test_missing_time_and_too_few_rows_get_the_csv_errors(tmp_path):
    csv_err, pq_err = _both(tmp_path, ["t", "q.shoulder"], [[0.0, 0.1], [0.01, 0.1]])
    assert "no 'time' column" in csv_err and "no 'time' column" in pq_err
    csv_err, pq_err = _both(tmp_path, HEADER, [[0.0, 0.1, 3e5]])
    assert "needs at least 2 rows, has 1" in csv_err and "needs at least 2 rows, has 1" in pq_err


def test_nulls_text_and_non_parquet_files_are_named(tmp_path):
    pq.write_table(pa.table({"time": [0.0, 0.01], "q.elbow": [0.1, None]}), tmp_path / "n.parquet")
    with pytest.raises(RecordingError, match=r"n.parquet: row 2, column 'q.elbow' is null"):
        read_parquet(tmp_path / "n.parquet")
    pq.write_table(pa.table({"time": [0.0, 0.01], "q.elbow": ["0.1", "0,2"]}), tmp_path / "s.parquet")
    with pytest.raises(RecordingError, match=r"s.parquet: column 'q.elbow' holds string values, expected numbers"):
        read_parquet(tmp_path / "s.parquet")
    (tmp_path / "x.parquet").write_text("time,q.elbow\n0,1\n")
    with pytest.raises(RecordingError, match="x.parquet: not a readable Parquet file"):
        read_parquet(tmp_path / "x.parquet")
    with pytest.raises(RecordingError, match="missing.parquet: recording not found"):
        read_parquet(tmp_path / "missing.parquet")


def test_integer_columns_are_numbers_and_validation_still_applies(tmp_path):
    t = np.arange(30) / 100
    pq.write_table(pa.table({"time": t, "q.shoulder": np.zeros(30), "q.elbow": np.zeros(30),
                             "p_a.shoulder": np.full(30, 3, dtype=np.int64)}), tmp_path / "bar.parquet")
    rec = read_parquet(tmp_path / "bar.parquet")
    assert rec["p_a.shoulder"].dtype == float
    with pytest.raises(RecordingError, match="column 'p_a.shoulder' is at most 3: looks like bar"), \
            pytest.warns(RecordingWarning, match="gauge pressure"):
        validate(rec, JOINTS, ACTS, need_commands=False, need_pressures=False)


def test_column_names_lose_a_byte_order_mark_and_spaces_as_in_a_csv_header(tmp_path):
    """A table converted from Excel's "CSV UTF-8" can carry the BOM in its first name."""
    pq.write_table(pa.table({"\ufefftime": [0.0, 0.01], " q.elbow ": [0.1, 0.2]}), tmp_path / "bom.parquet")
    rec = read_parquet(tmp_path / "bom.parquet")
    assert list(rec.columns) == ["q.elbow"] and rec.time.tolist() == [0.0, 0.01]
    pq.write_table(pa.table({"time": [0.0, 0.01], "q.elbow": [0.1, 0.2], "q.elbow ": [0.1, 0.2]}),
                   tmp_path / "dup.parquet")
    with pytest.raises(RecordingError, match="dup.parquet: repeated column\\(s\\) \\['q.elbow'\\]"):
        read_parquet(tmp_path / "dup.parquet")


def test_metadata_fields_are_checked_as_a_sidecars_are(tmp_path):
    """A Parquet file's metadata carries what a CSV's sidecar does, so the fields pneumasim reads
    get the sidecar's type checks, naming the file and the field."""
    rec = arm2_like()
    rec.meta["rate_hz"] = "fast"
    rec.to_parquet(tmp_path / "r.parquet")
    with pytest.raises(RecordingError, match=r"r.parquet: metadata field 'rate_hz' must be a positive number"):
        read_parquet(tmp_path / "r.parquet")
    rec.meta["rate_hz"] = 100.0
    rec.to_parquet(tmp_path / "r.parquet")
    assert read_parquet(tmp_path / "r.parquet").meta["rate_hz"] == 100.0
