"""pneumasim import: unit and number-format conversions and error messages, on unchanged slices
of the thesis logs (tests/data, CC0) and on small hand-made files."""
import json
from pathlib import Path

import numpy as np
import pytest

from pneumasim.cli import main as cli_main
from pneumatics.errors import ConfigError, RecordingError
from pneumatics.importer import import_file, load_map, parse_number, shipped_maps
from pneumatics.recording import read_csv

DATA = Path(__file__).parent / "data"
ATM = 101325.0


def test_shipped_maps_exist_for_both_kinds_of_thesis_file():
    assert {"zillen_chamber", "zillen_friction"} <= set(shipped_maps())
    for path in shipped_maps().values():
        load_map(path)  # every shipped map is valid


@pytest.mark.parametrize("cell, decimal, thousands, value", [
    ("902.000", ".", ".", 902.0),
    ("1.002.000", ".", ".", 1002.0),          # the chamber logs: '.' both ways, last one is decimal
    ("151.303.000", ".", ".", 151303.0),
    ("1,234.5", ".", ",", 1234.5),
    ("1.234,5", ",", ".", 1234.5),
    ("-0,25", ",", "", -0.25),
    ("7.315", ".", "", 7.315),
])
def test_number_formats(cell, decimal, thousands, value):
    assert parse_number(cell, decimal, thousands) == pytest.approx(value)


@pytest.mark.parametrize("cell, decimal, thousands", [
    ("1.02.000", ".", "."),     # a thousands group of two digits
    ("1,23.5", ".", ","),
    ("1.5", ",", ""),           # '.' where ',' is the decimal mark
    ("abc", ".", ""),
])
def test_malformed_numbers_are_rejected(cell, decimal, thousands):
    with pytest.raises(ValueError):
        parse_number(cell, decimal, thousands)


def test_chamber_log_ms_with_thousands_dots_and_gauge_bar():
    rec = import_file(DATA / "zillen_chamber_slice.csv", "zillen_chamber")
    # rows 0, 100, 200 ... 903 ms, then "1.003.000" = 1003 ms
    assert rec.time[:3] == pytest.approx([0.0, 0.1, 0.2])
    assert rec.time[9] == pytest.approx(0.903)
    assert rec.time[10] == pytest.approx(1.003)
    assert np.all(np.diff(rec.time) > 0)
    # 7.315 bar gauge -> absolute Pa with the map's stated atmosphere
    assert rec["p_a.chamber"][0] == pytest.approx(7.315e5 + ATM)
    assert rec["sensor_v.chamber"][0] == pytest.approx(3.658)
    assert rec.meta["model"] == "bench_chamber"


def test_friction_log_mm_to_m_and_forces():
    rec = import_file(DATA / "zillen_friction_slice.csv", "zillen_friction")
    assert rec.time[1] == pytest.approx(0.011)
    assert rec["q.rod"][0] == pytest.approx(-0.009e-3)    # -0.009 mm
    assert rec["p_a.rod"][0] == pytest.approx(0.996e5 + ATM)
    assert rec["force.rod"][0] == pytest.approx(49.749)
    assert set(rec.columns) >= {"q.rod", "p_a.rod", "force.rod"}


def _map(tmp_path, body: str, name="m.toml") -> Path:
    path = tmp_path / name
    path.write_text(body)
    return path


BASE = """
[source]
delimiter = ";"
decimal = ","
thousands = "."
atmosphere_pa = 100000.0
[[column]]
source = 1
name = "t"
unit = "ms"
target = "time"
[[column]]
source = 2
name = "druck"
unit = "kPa_gauge"
target = "p_a.cyl"
[[column]]
source = 3
name = "kraft"
unit = "kN"
target = "force.cyl"
"""


def test_comma_decimal_and_kilo_units(tmp_path):
    src = tmp_path / "log.csv"
    src.write_text("0;250,5;0,1\n1.500;300;1,25\n")
    rec = import_file(src, _map(tmp_path, BASE))
    assert rec.time == pytest.approx([0.0, 1.5])
    assert rec["p_a.cyl"] == pytest.approx([250.5e3 + 1e5, 300e3 + 1e5])
    assert rec["force.cyl"] == pytest.approx([100.0, 1250.0])


def test_unparsable_cell_names_file_line_and_column(tmp_path):
    src = tmp_path / "log.csv"
    src.write_text("0;250,5;0,1\n1.500;3x0;1,25\n")
    with pytest.raises(RecordingError) as e:
        import_file(src, _map(tmp_path, BASE))
    msg = str(e.value)
    assert "log.csv" in msg and "line 2" in msg and "column 2" in msg and "druck" in msg and "3x0" in msg


def test_time_going_backwards_names_the_line(tmp_path):
    src = tmp_path / "log.csv"
    src.write_text("0;1;1\n2.000;1;1\n1.000;1;1\n")
    with pytest.raises(RecordingError, match="line 3.*not increasing"):
        import_file(src, _map(tmp_path, BASE))


def test_short_row_is_an_error(tmp_path):
    src = tmp_path / "log.csv"
    src.write_text("0;1;1\n1.000;1\n")
    with pytest.raises(RecordingError, match="line 2 has 2 field"):
        import_file(src, _map(tmp_path, BASE))


@pytest.mark.parametrize("edit, match", [
    (('unit = "kN"', 'unit = "kilonewton"'), "column #3: unknown unit 'kilonewton'"),
    (('unit = "kN"', 'unit = "mm"'), "column #3: target 'force.cyl' needs a force unit"),
    (("atmosphere_pa = 100000.0\n", ""), "gauge pressure: state source.atmosphere_pa"),
    (('target = "time"', 'target = "t"'), "no column maps to 'time'"),
    (('source = 3', 'source = 0'), "column #3: source = 0"),
    (('delimiter = ";"', 'delimiter = ";;"'), "source.delimiter"),
    (('unit = "kN"\ntarget = "force.cyl"', 'unit = "kPa_gauge"\ntarget = "p_a.cyl"'), "both map to 'p_a.cyl'"),
    (('name = "kraft"', 'nmae = "kraft"'), "unknown field"),
])
def test_bad_maps_name_the_file_and_field(tmp_path, edit, match):
    path = _map(tmp_path, BASE.replace(*edit), "bad.toml")
    with pytest.raises(ConfigError, match=match) as e:
        load_map(path)
    assert "bad.toml" in str(e.value)


def test_missing_map_lists_the_shipped_ones(tmp_path):
    with pytest.raises(ConfigError, match="zillen_chamber"):
        load_map(tmp_path / "nope.toml")


def test_cli_import_writes_a_readable_recording_with_metadata(tmp_path):
    out = tmp_path / "rec.csv"
    cli_main(["import", str(DATA / "zillen_friction_slice.csv"), "--map", "zillen_friction",
              "--out", str(out), "--meta", "bore_m=0.0257"])
    rec = read_csv(out)
    assert len(rec) == 20 and rec["force.rod"][0] == pytest.approx(49.749)
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["bore_m"] == pytest.approx(0.0257) and meta["model"] == "bench_cylinder"
