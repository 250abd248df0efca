"""Import a lab's raw log into a pneumasim recording (DESIGN.md "Recordings").

A mapping file (TOML) says how to read the source and what each column is::

    [source]
    delimiter = ";"           # one character, or "whitespace"
    header_rows = 0           # lines to skip before the data
    decimal = "."             # decimal mark
    thousands = "."           # thousands separator ("" = none); if it equals the decimal
                              # mark, the last mark in a number is the decimal point
    atmosphere_pa = 101325.0  # room pressure [Pa abs], required by gauge units

    [meta]                    # copied into the recording's sidecar <name>.json
    model = "bench_chamber"

    [[column]]
    source = 1                # 1-based column number in the source
    name = "time"             # the source's own name for it (used in messages)
    unit = "ms"               # unit of the source values (see UNITS)
    target = "time"           # recording channel: time, q.<joint>, p_a.<actuator>, force.<actuator>, ...
    scale = 1.0               # optional factor applied before the unit conversion

A map for ROS bags has a ``[ros]`` section instead of ``[[column]]`` entries (which topic and
field gives which channel, the time base; :mod:`pneumatics.formats.rosbag_map`).
Every value becomes SI (pressures absolute, in Pa).  A bad map raises :class:`ConfigError`
naming the map file and field; an unparsable cell raises :class:`RecordingError` naming the
source file, line and column.  Maps for the lab files pneumasim knows ship in
``pneumatics/import_maps/`` (:func:`shipped_maps`).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .config import read_toml
from .errors import ConfigError, RecordingError, UnknownNameError
from .recording import Recording

MAPS_DIR = Path(__file__).resolve().parent / "import_maps"

#: unit -> (quantity, factor to SI, gauge?)  (gauge pressures get + atmosphere_pa)
UNITS = {
    "s": ("time", 1.0, False), "ms": ("time", 1e-3, False), "us": ("time", 1e-6, False),
    "min": ("time", 60.0, False),
    "m": ("length", 1.0, False), "cm": ("length", 1e-2, False), "mm": ("length", 1e-3, False),
    "um": ("length", 1e-6, False), "in": ("length", 0.0254, False),
    "rad": ("angle", 1.0, False), "deg": ("angle", math.pi / 180.0, False),
    "m/s": ("velocity", 1.0, False), "mm/s": ("velocity", 1e-3, False),
    "rad/s": ("angular_velocity", 1.0, False), "deg/s": ("angular_velocity", math.pi / 180.0, False),
    "Pa": ("pressure", 1.0, False), "kPa": ("pressure", 1e3, False), "MPa": ("pressure", 1e6, False),
    "bar": ("pressure", 1e5, False), "psi": ("pressure", 6894.757293168, False),
    "Pa_gauge": ("pressure", 1.0, True), "kPa_gauge": ("pressure", 1e3, True),
    "MPa_gauge": ("pressure", 1e6, True), "bar_gauge": ("pressure", 1e5, True),
    "psi_gauge": ("pressure", 6894.757293168, True),
    "N": ("force", 1.0, False), "kN": ("force", 1e3, False), "lbf": ("force", 4.4482216152605, False),
    "N*m": ("torque", 1.0, False), "N*mm": ("torque", 1e-3, False),
    "V": ("voltage", 1.0, False), "mV": ("voltage", 1e-3, False),
    "A": ("current", 1.0, False), "mA": ("current", 1e-3, False),
    "1": ("number", 1.0, False),
}

#: recording prefix -> quantities its unit may have (other prefixes: extra columns, any unit)
TARGET_QUANTITY = {
    "time": ("time",), "q": ("length", "angle"), "ref": ("length", "angle"),
    "qd": ("velocity", "angular_velocity"), "p_a": ("pressure",), "p_b": ("pressure",),
    "u_a": ("voltage",), "u_b": ("voltage",), "i": ("current",), "force": ("force",),
    "tau": ("torque",),
}

TARGET_PATTERN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z0-9_]+)?$")


@dataclass(frozen=True)
class ColumnMap:
    source: int
    """1-based column number in the source file"""
    name: str
    """the source's name for the column (for messages)"""
    unit: str
    """unit of the source values, a key of :data:`UNITS`"""
    target: str
    """recording channel (DESIGN.md): time, q.<joint>, p_a.<actuator>, force.<actuator>, ..."""
    scale: float = 1.0
    """factor applied to the source value before the unit conversion"""


@dataclass(frozen=True)
class ImportMap:
    path: str
    delimiter: str | None
    """one character, or None for any whitespace"""
    header_rows: int
    decimal: str
    thousands: str
    atmosphere_pa: float | None
    columns: tuple
    meta: dict = field(default_factory=dict)
    ros: dict | None = None
    """the raw ``[ros]`` section, checked by :func:`pneumatics.formats.rosbag_map.ros_map`"""

    def to_si(self, col: ColumnMap, values: np.ndarray) -> np.ndarray:
        """Source values (N,) of ``col`` in SI units, pressures absolute."""
        _, factor, gauge = UNITS[col.unit]
        out = values * col.scale * factor
        return out + self.atmosphere_pa if gauge else out


def shipped_maps() -> dict[str, Path]:
    """Name -> path of the mapping files that ship with pneumasim."""
    return {p.stem: p for p in sorted(MAPS_DIR.glob("*.toml"))}


def load_map(path_or_name: str | Path) -> ImportMap:
    """Read and check a mapping file (a path, or the name of a shipped map)."""
    path = Path(path_or_name)
    if not path.is_file():
        shipped = shipped_maps()
        if str(path_or_name) in shipped:
            path = shipped[str(path_or_name)]
        elif path.suffix or len(path.parts) > 1:  # a file name: the file is missing
            raise ConfigError(f"{path}: mapping file not found (shipped maps: {', '.join(shipped)})")
        else:  # a bare name: one of the shipped maps, perhaps misspelt
            raise UnknownNameError("import map", str(path), shipped)
    doc = read_toml(path, "mapping file")
    where = str(path)
    unknown = set(doc) - {"source", "meta", "column", "ros"}
    if unknown:
        raise ConfigError(f"{where}: unknown section(s) {sorted(unknown)}; valid: source, meta, column, ros")
    ros = doc.get("ros")
    if ros is not None and not isinstance(ros, dict):
        raise ConfigError(f"{where}: [ros] must be a table")
    src = doc.get("source", {})
    if not isinstance(src, dict):
        raise ConfigError(f"{where}: [source] must be a table")
    bad = set(src) - {"delimiter", "header_rows", "decimal", "thousands", "atmosphere_pa"}
    if bad:
        raise ConfigError(f"{where}: [source] has unknown field(s) {sorted(bad)}; valid: delimiter, "
                          "header_rows, decimal, thousands, atmosphere_pa")
    delim = src.get("delimiter", ",")
    if not isinstance(delim, str) or (delim != "whitespace" and len(delim) != 1):
        raise ConfigError(f"{where}: source.delimiter = {delim!r}: expected one character or \"whitespace\"")
    decimal, thousands = src.get("decimal", "."), src.get("thousands", "")
    if decimal not in (".", ","):
        raise ConfigError(f"{where}: source.decimal = {decimal!r}: expected '.' or ','")
    if thousands not in ("", ".", ",", " ", "'"):
        raise ConfigError(f"{where}: source.thousands = {thousands!r}: expected '', '.', ',', ' ' or \"'\"")
    if thousands and thousands == delim:
        raise ConfigError(f"{where}: source.thousands {thousands!r} is also the delimiter")
    header_rows = src.get("header_rows", 0)
    if not isinstance(header_rows, int) or header_rows < 0:
        raise ConfigError(f"{where}: source.header_rows = {header_rows!r}: expected an integer >= 0")
    atm = src.get("atmosphere_pa")
    if atm is not None and (isinstance(atm, bool) or not isinstance(atm, (int, float)) or not 5e4 <= atm <= 1.2e5):
        raise ConfigError(f"{where}: source.atmosphere_pa = {atm!r}: expected a room pressure in Pa "
                          "(absolute, 50000-120000)")
    cols = doc.get("column", [] if ros is not None else None)
    if not isinstance(cols, list) or (not cols and ros is None):
        raise ConfigError(f"{where}: no [[column]] entries: the map must name at least the time column")
    columns, targets = [], {}
    for n, c in enumerate(cols, 1):
        columns.append(_column(c, f"{where}: column #{n}", atm))
        t = columns[-1].target
        if t in targets:
            raise ConfigError(f"{where}: column #{n} and #{targets[t]} both map to {t!r}")
        targets[t] = n
    if cols and "time" not in targets:
        raise ConfigError(f"{where}: no column maps to 'time'")
    meta = doc.get("meta", {})
    if not isinstance(meta, dict):
        raise ConfigError(f"{where}: [meta] must be a table")
    return ImportMap(where, None if delim == "whitespace" else delim, header_rows, decimal,
                     thousands, None if atm is None else float(atm), tuple(columns), dict(meta), ros)


def _column(c, where: str, atm) -> ColumnMap:
    if not isinstance(c, dict):
        raise ConfigError(f"{where}: expected a table")
    bad = set(c) - {"source", "name", "unit", "target", "scale"}
    if bad:
        raise ConfigError(f"{where}: unknown field(s) {sorted(bad)}; valid: source, name, unit, target, scale")
    for key in ("source", "unit", "target"):
        if key not in c:
            raise ConfigError(f"{where}: missing field {key!r}")
    src, unit, target = c["source"], c["unit"], c["target"]
    if isinstance(src, bool) or not isinstance(src, int) or src < 1:
        raise ConfigError(f"{where}: source = {src!r}: expected a 1-based column number")
    if unit not in UNITS:
        raise ConfigError(f"{where}: unknown unit {unit!r}; valid: {', '.join(UNITS)}")
    if not isinstance(target, str) or not TARGET_PATTERN.match(target):
        raise ConfigError(f"{where}: target = {target!r}: expected a channel such as 'time', 'q.rod', "
                          "'p_a.chamber', 'force.rod'")
    quantity, _, gauge = UNITS[unit]
    allowed = TARGET_QUANTITY.get(target.split(".", 1)[0])
    if allowed and quantity not in allowed:
        raise ConfigError(f"{where}: target {target!r} needs a {' or '.join(allowed)} unit, got {unit!r} ({quantity})")
    if gauge and atm is None:
        raise ConfigError(f"{where}: unit {unit!r} is a gauge pressure: state source.atmosphere_pa "
                          "(room pressure, Pa) to make it absolute")
    scale = c.get("scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not math.isfinite(scale) or scale == 0:
        raise ConfigError(f"{where}: scale = {scale!r}: expected a finite non-zero number")
    return ColumnMap(src, str(c.get("name", f"column {src}")), unit, target, float(scale))


def parse_number(cell: str, decimal: str, thousands: str) -> float:
    """One number in the map's format; ValueError if it does not fit it.

    ``thousands == decimal`` (as in logs that print 1002 ms as ``1.002.000``): the last mark
    is the decimal point and every group before it has three digits.
    """
    s = cell.strip()
    if thousands:
        if thousands == decimal:
            head, mark, frac = s.rpartition(decimal)
            groups = head.split(thousands) if mark else []
            if mark and len(groups) > 1 and any(len(g.lstrip("+-")) != 3 for g in groups[1:]):
                raise ValueError(s)
            s = ("".join(groups) + "." + frac) if mark else s
            return float(s)
        if thousands in s:
            int_part = s.split(decimal)[0]
            groups = int_part.split(thousands)
            if any(len(g) != 3 for g in groups[1:]) or not groups[0].lstrip("+-"):
                raise ValueError(s)
            s = s.replace(thousands, "")
    if decimal != ".":
        if "." in s:
            raise ValueError(s)
        s = s.replace(decimal, ".")
    if "_" in s:
        raise ValueError(s)
    return float(s)


def import_file(src: str | Path, mapping: ImportMap | str | Path, meta: dict | None = None) -> Recording:
    """Read lab log ``src`` with ``mapping`` into a :class:`Recording` (SI, absolute pressures)."""
    imap = mapping if isinstance(mapping, ImportMap) else load_map(mapping)
    src = Path(src)
    if not imap.columns:
        raise ConfigError(f"{imap.path}: no [[column]] entries: this map reads ROS bags ([ros]); "
                          f"{src} is not one (.bag, .db3, .mcap or a ROS 2 bag folder)")
    try:
        lines = src.read_text().splitlines()
    except FileNotFoundError:
        raise RecordingError(f"{src}: source file not found") from None
    except UnicodeDecodeError:
        raise RecordingError(f"{src}: not a text file") from None
    need = max(c.source for c in imap.columns)
    rows, line_no = [], []
    for n, line in enumerate(lines, 1):
        if n <= imap.header_rows or not line.strip():
            continue
        cells = line.split() if imap.delimiter is None else line.split(imap.delimiter)
        if len(cells) < need:
            raise RecordingError(f"{src}: line {n} has {len(cells)} field(s), map {imap.path} reads column {need}")
        row = []
        for c in imap.columns:
            cell = cells[c.source - 1]
            try:
                v = parse_number(cell, imap.decimal, imap.thousands)
            except ValueError:
                raise RecordingError(
                    f"{src}: line {n}, column {c.source} ({c.name!r}): {cell.strip()!r} is not a number "
                    f"(map {Path(imap.path).name}: decimal {imap.decimal!r}, thousands {imap.thousands!r})") from None
            if not math.isfinite(v):
                raise RecordingError(f"{src}: line {n}, column {c.source} ({c.name!r}) is {cell.strip()!r}")
            row.append(v)
        rows.append(row)
        line_no.append(n)
    if len(rows) < 2:
        raise RecordingError(f"{src}: fewer than 2 data rows after {imap.header_rows} header row(s)")
    data = np.array(rows)
    values = {c.target: imap.to_si(c, data[:, j]) for j, c in enumerate(imap.columns)}
    t = values.pop("time")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0))
        tc = next(c for c in imap.columns if c.target == "time")
        raise RecordingError(f"{src}: line {line_no[i + 1]}, column {tc.source} ({tc.name!r}): time is not "
                             f"increasing ({t[i]:.6g} s then {t[i + 1]:.6g} s) — wrong number format or unit in the map?")
    full_meta = {**imap.meta, "imported_from": str(src), "import_map": str(imap.path), **(meta or {})}
    return Recording(t, values, full_meta, str(src))


def sidecar_path(out: str | Path) -> Path:
    """The sidecar of recording ``out``: REC.csv -> REC.json (DESIGN.md "Recordings")."""
    return Path(out).with_suffix(".json")
