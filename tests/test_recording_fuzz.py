"""Property-based tests of the CSV reader (issue 18, input side, item 4): random valid
recordings round-trip exactly whatever the lab's dialect (BOM, CRLF, comma, semicolon or tab);
random corruptions give a PneumasimError, or are read correctly — never another exception."""
import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pneumatics.errors import PneumasimError
from pneumatics.recording import Recording, RecordingWarning, read_csv

NAMES = ["q.shoulder", "q.elbow", "p_a.shoulder", "p_b.elbow", "u_a.elbow", "extra_col"]
finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False)
SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@st.composite
def recordings(draw):
    n = draw(st.integers(2, 25))
    names = draw(st.lists(st.sampled_from(NAMES), unique=True, min_size=1, max_size=len(NAMES)))
    steps = draw(st.lists(st.floats(1e-6, 10.0), min_size=n - 1, max_size=n - 1))
    t0 = draw(st.floats(-100.0, 100.0))
    time = t0 + np.concatenate([[0.0], np.cumsum(steps)])
    if np.any(np.diff(time) <= 0):  # rounding made two instants equal: space them out
        time = t0 + np.arange(n) * 1e-3
    cols = {c: np.array(draw(st.lists(finite, min_size=n, max_size=n))) for c in names}
    return Recording(time, cols)


def render(rec: Recording, delim=",", newline="\n", bom=False) -> str:
    """The recording as a lab would write it, every number with repr (an exact round trip)."""
    rows = [delim.join(["time", *rec.columns])]
    for k in range(len(rec)):
        rows.append(delim.join(repr(float(v)) for v in [rec.time[k], *(c[k] for c in rec.columns.values())]))
    return ("\ufeff" if bom else "") + newline.join(rows) + newline


def same(a: Recording, b: Recording) -> bool:
    return (np.array_equal(a.time, b.time) and list(a.columns) == list(b.columns)
            and all(np.array_equal(a.columns[c], b.columns[c]) for c in a.columns))


@SETTINGS
@given(rec=recordings(), delim=st.sampled_from([",", ";", "\t"]), newline=st.sampled_from(["\n", "\r\n"]),
       bom=st.booleans())
def test_valid_recordings_round_trip_exactly_in_every_dialect(tmp_path_factory, rec, delim, newline, bom):
    path = tmp_path_factory.mktemp("rt") / "r.csv"
    path.write_bytes(render(rec, delim, newline, bom).encode("utf-8"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = read_csv(path)
    assert same(rec, back)


def corrupt(text: str, kind: str, data) -> str:
    lines = text.splitlines()
    if kind == "drop_cell":
        i = data.draw(st.integers(1, len(lines) - 1))
        cells = lines[i].split(",")
        del cells[data.draw(st.integers(0, len(cells) - 1))]
        lines[i] = ",".join(cells)
    elif kind in ("text_in_number", "nan", "inf", "empty_cell"):
        i = data.draw(st.integers(1, len(lines) - 1))
        cells = lines[i].split(",")
        new = {"text_in_number": data.draw(st.sampled_from(["abc", "1.2.3", "--4", "1e", "0x10", "n/a"])),
               "nan": "nan", "inf": data.draw(st.sampled_from(["inf", "-inf", "1e999"])), "empty_cell": ""}[kind]
        cells[data.draw(st.integers(0, len(cells) - 1))] = new
        lines[i] = ",".join(cells)
    elif kind == "shuffle_time":
        body = lines[1:]
        order = data.draw(st.permutations(range(len(body))))
        lines = lines[:1] + [body[k] for k in order]
    elif kind == "truncate":
        return text[:data.draw(st.integers(0, len(text) - 1))]
    elif kind == "duplicate_row":
        i = data.draw(st.integers(1, len(lines) - 1))
        lines.insert(i, lines[i])
    elif kind == "garbage_bytes":
        i = data.draw(st.integers(0, len(text)))
        return text[:i] + data.draw(st.sampled_from(["\x00", "\udcff", "\x1a", ";;", "\"", "\t"])) + text[i:]
    return "\n".join(lines) + "\n"


KINDS = ["drop_cell", "text_in_number", "nan", "inf", "empty_cell", "shuffle_time", "truncate", "duplicate_row",
         "garbage_bytes"]


@SETTINGS
@given(rec=recordings(), kind=st.sampled_from(KINDS), data=st.data())
def test_corruptions_give_a_pneumasim_error_or_a_correct_reading(tmp_path_factory, rec, kind, data):
    text = render(rec)
    bad = corrupt(text, kind, data)
    path = tmp_path_factory.mktemp("bad") / "r.csv"
    path.write_bytes(bad.encode("utf-8", "surrogateescape"))
    try:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            back = read_csv(path)
    except PneumasimError as e:
        assert str(path) in str(e) and "\n" not in str(e)
        return
    # read: every value is finite and time strictly increasing, and what was read is what the
    # file holds — the original (a permutation that kept the order, a harmless byte) or, for a
    # cut file, a prefix of its rows whose last row may be incomplete only with a warning
    assert np.all(np.diff(back.time) > 0)
    assert all(np.all(np.isfinite(v)) for v in back.columns.values())
    if same(rec, back):
        return
    assert kind in ("truncate", "garbage_bytes", "drop_cell", "text_in_number"), kind
    n = len(back)
    if kind == "truncate":
        head = Recording(rec.time[:n], {c: v[:n] for c, v in rec.columns.items() if c in back.columns})
        cut_last = any(issubclass(w.category, RecordingWarning) and "no line end" in str(w.message) for w in said)
        if not same(head, back):
            assert cut_last and np.array_equal(head.time[:-1], back.time[:-1])
    else:  # a byte or cell change that still parses: the reader read exactly that number, no crash
        assert math.isfinite(float(back.time[0]))


def test_bom_is_not_part_of_the_first_column_name(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_bytes("\ufefftime;q.elbow\r\n0;0,5\r\n0,01;0,25\r\n".encode("utf-8"))
    rec = read_csv(path)
    assert list(rec.columns) == ["q.elbow"] and np.allclose(rec["q.elbow"], [0.5, 0.25])
    assert np.allclose(rec.time, [0.0, 0.01])


def test_unknown_delimiter_is_named(tmp_path):
    path = tmp_path / "spaces.csv"
    path.write_text("time q.elbow\n0 1\n")
    with pytest.raises(PneumasimError, match="separated by spaces; pneumasim reads comma, semicolon or tab"):
        read_csv(path)


def test_utf16_is_named(tmp_path):
    path = tmp_path / "u16.csv"
    path.write_bytes("time,q.elbow\n0,1\n0.1,2\n".encode("utf-16"))
    with pytest.raises(PneumasimError, match="UTF-16 text .* save it as 'CSV UTF-8'"):
        read_csv(path)


@pytest.mark.parametrize("sidecar, match", [
    ("[1, 2]", "sidecar must be a JSON object .* got a JSON array"),
    ('"arm2"', "got a JSON string"),
    ('{"model": 2}', "field 'model' must be a model name, got 2"),
    ('{"daq_averaging": "false"}', "field 'daq_averaging' must be true or false, got \"false\""),
    ('{"rate_hz": -100}', "field 'rate_hz' must be a positive number \\[Hz\\], got -100"),
    ('{"room_pa": "101325"}', "field 'room_pa' must be a positive number \\[Pa abs\\]"),
    ('{"braced": 1}', "field 'braced' must be true or false"),
    ("{model: arm2}", "sidecar is not valid JSON"),
])
def test_sidecar_is_validated(tmp_path, sidecar, match):
    (tmp_path / "r.csv").write_text("time,q.elbow\n0,1\n0.1,2\n")
    (tmp_path / "r.json").write_text(sidecar)
    with pytest.raises(PneumasimError, match=match):
        read_csv(tmp_path / "r.csv")


def test_sidecar_with_bom_and_extra_fields_is_read(tmp_path):
    (tmp_path / "r.csv").write_text("time,q.elbow\n0,1\n0.1,2\n")
    (tmp_path / "r.json").write_bytes('\ufeff{"model": "arm2", "daq_averaging": false, "operator": ["x"]}'.encode())
    assert read_csv(tmp_path / "r.csv").meta == {"model": "arm2", "daq_averaging": False, "operator": ["x"]}
