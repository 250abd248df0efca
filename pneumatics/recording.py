"""Recordings: what the robot (or the simulator) logged, in the CSV format of DESIGN.md.

One header row, one row per sample, strictly increasing ``time`` [s]; columns ``q.<joint>``
[rad|m], optional ``qd.<joint>``, ``p_a.<actuator>`` / ``p_b.<actuator>`` [Pa abs],
``u_a.<actuator>`` / ``u_b.<actuator>`` [V] (or ``i.<actuator>`` [A]), optional
``force.<actuator>`` [N], ``tau.<joint>`` [N m], ``ref.<joint>``.  Extra columns are kept.
A sidecar ``<name>.json`` holds metadata.  Timing convention (as the DAQ of paper 002):
row k's sensors are the mean over the control period ending at ``time[k]``; row k's commands
are held from ``time[k]`` to ``time[k+1]``.
"""
from __future__ import annotations

import csv
import io
import json
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import RecordingError
from .formats import parquet
from .formats.rows import check_rows
from .io import atomic_write_text

KNOWN_PREFIXES = ("q", "qd", "p_a", "p_b", "u_a", "u_b", "i", "force", "tau", "ref")
JOINT_PREFIXES = ("q", "qd", "tau", "ref")
ACTUATOR_PREFIXES = ("p_a", "p_b", "u_a", "u_b", "i", "force")


class RecordingWarning(UserWarning):
    """Something in a recording looks wrong but may be intended."""


@dataclass
class Recording:
    """A table of named 1-D channels sampled at ``time``.

    Attributes:
      time: (N,) seconds, strictly increasing.
      columns: name -> (N,) float array, in file order (``time`` excluded).
      meta: sidecar metadata (model, rates, notes, ...).
    """

    time: np.ndarray
    columns: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)
    source: str = "<memory>"

    def __getitem__(self, name: str) -> np.ndarray:
        if name == "time":
            return self.time
        if name not in self.columns:
            raise RecordingError(f"{self.source}: no column {name!r}; columns: {', '.join(self.columns)}")
        return self.columns[name]

    def __contains__(self, name: str) -> bool:
        return name == "time" or name in self.columns

    def __len__(self) -> int:
        return self.time.size

    @property
    def rate_hz(self) -> float:
        return float(1.0 / np.median(np.diff(self.time))) if self.time.size > 1 else float("nan")

    def names(self, prefix: str) -> list[str]:
        """Names after ``prefix.`` in column order, e.g. names("q") -> ["shoulder", "elbow"]."""
        return [c.split(".", 1)[1] for c in self.columns if c.split(".", 1)[0] == prefix and "." in c]

    def matrix(self, prefix: str, names) -> np.ndarray:
        """(N, len(names)) stack of ``prefix.<name>`` columns."""
        return np.column_stack([self[f"{prefix}.{n}"] for n in names])

    def slice(self, t0: float, t1: float) -> "Recording":
        """Rows with t0 <= time < t1 (a view-free copy)."""
        m = (self.time >= t0) & (self.time < t1)
        return Recording(self.time[m].copy(), {k: v[m].copy() for k, v in self.columns.items()},
                         dict(self.meta), f"{self.source}[{t0:g}:{t1:g}]")

    # -- files -----------------------------------------------------------------------------
    def to_csv(self, path: str | Path, digits: int = 7, sidecar: str | Path | None = None):
        """Write ``path`` (and the sidecar, ``<path>.json`` unless given, if meta is non-empty)
        atomically."""
        path = Path(path)
        buf = io.StringIO()
        names = ["time", *self.columns]
        buf.write(",".join(names) + "\n")
        data = np.column_stack([self.time, *self.columns.values()])
        np.savetxt(buf, data, delimiter=",", fmt=f"%.{digits}g")
        atomic_write_text(path, buf.getvalue())
        if self.meta:
            atomic_write_text(sidecar or path.with_suffix(".json"), json.dumps(self.meta, indent=1) + "\n")

    def to_parquet(self, path: str | Path):
        """Write ``path`` as Parquet atomically; the metadata goes into the schema metadata."""
        parquet.write_table(path, self.time, self.columns, self.meta)

    def write(self, path: str | Path):
        """Write by suffix: ``.csv`` (+ sidecar ``.json``) or ``.parquet``."""
        suffix = Path(path).suffix.lower()
        if suffix not in WRITERS:
            raise RecordingError(f"{path}: cannot write a recording as {suffix or 'no suffix'!r}; "
                                 f"valid: {', '.join(WRITERS)} (ROS bags: pneumatics.formats.rosbag_write.write_bag)")
        getattr(self, WRITERS[suffix])(path)


WRITERS = {".csv": "to_csv", ".parquet": "to_parquet"}


#: delimiters a recording may use (Excel in a locale with a decimal comma writes semicolons)
DELIMITERS = {",": "comma", ";": "semicolon", "\t": "tab"}
#: sidecar fields pneumasim reads -> (type(s) expected, description); other fields are kept as they are
SIDECAR_FIELDS = {
    "model": (str, "a model name"),
    "daq_averaging": (bool, "true or false"),
    "rate_hz": ("positive", "a positive number [Hz]"),
    "physics_dt_s": ("positive", "a positive number [s]"),
    "room_pa": ("positive", "a positive number [Pa abs]"),
    "supply_pa": ("positive", "a positive number [Pa abs]"),
    "bore_m": ("positive", "a positive number [m]"),
    "volume_m3": ("positive", "a positive number [m^3]"),
    "braced": (bool, "true or false (the load locked by a brace, as paper 001's Fig. 2a)"),
}


def read_csv(path: str | Path) -> Recording:
    """Read a recording; raises :class:`RecordingError` naming file, row and column.

    Accepts what lab software writes: UTF-8 with or without a byte-order mark (Excel's
    "CSV UTF-8"), LF or CRLF line ends, and a comma, semicolon or tab delimiter (detected from
    the header row; with a semicolon or tab, a decimal comma "0,25" is read as 0.25)."""
    path = Path(path)
    text = _read_text(path)
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise RecordingError(f"{path}: empty file")
    if len(lines) > 1 and not text.endswith(("\n", "\r")):
        warnings.warn(f"{path}: the last line (row {len(lines)}) has no line end: if the file was cut short "
                      "(a copy or a logger stopped mid-write), its last row may be incomplete", RecordingWarning,
                      stacklevel=2)
    delim = _delimiter(path, lines[0])
    rows = [r for r in csv.reader(lines, delimiter=delim) if r and any(c.strip() for c in r)]
    header = [h.strip() for h in rows[0]]
    if "time" not in header:
        raise RecordingError(f"{path}: no 'time' column in the header (read as {DELIMITERS[delim]}-separated, "
                             f"got {', '.join(map(repr, header[:8]))}{'...' if len(header) > 8 else ''})")
    dup = {h for h in header if header.count(h) > 1}
    if dup:
        raise RecordingError(f"{path}: repeated column(s) {sorted(dup)}")
    data = _numbers(path, rows[1:], header, decimal_comma=delim != ",")
    check_rows(path, header, data, first=2, word="line")
    t = data[:, header.index("time")]
    columns = {h: data[:, j].copy() for j, h in enumerate(header) if h != "time"}
    side = path.with_suffix(".json")
    meta = read_sidecar(side) if side.is_file() else {}
    return Recording(t.copy(), columns, meta, str(path))


def read_parquet(path: str | Path) -> Recording:
    """Read a Parquet recording with the checks of :func:`read_csv` (formats/parquet.py)."""
    t, columns, meta = parquet.read_table(path)
    return Recording(t, columns, check_metadata(meta, f"{path}: metadata"), str(path))


def _read_text(path: Path) -> str:
    """The file's text: UTF-8, a leading byte-order mark dropped; UTF-16 named in the error."""
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise RecordingError(f"{path}: recording not found") from None
    except IsADirectoryError:
        raise RecordingError(f"{path}: is a folder, not a recording (CSV) file") from None
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise RecordingError(f"{path}: UTF-16 text (Excel's 'Unicode Text'); save it as 'CSV UTF-8' "
                             "or plain CSV")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise RecordingError(f"{path}: not a UTF-8 text (CSV) file (byte {e.start} cannot be read)") from None


def _delimiter(path: Path, header_line: str) -> str:
    """The delimiter the header row uses: the most frequent of comma, semicolon and tab."""
    counts = {d: header_line.count(d) for d in DELIMITERS}
    best = max(counts, key=counts.get)
    if counts[best] == 0:
        if header_line.strip() == "time":
            return ","
        others = "spaces" if len(header_line.split()) > 1 else "nothing pneumasim knows"
        raise RecordingError(f"{path}: the header row {header_line[:60]!r} is separated by {others}; "
                             f"pneumasim reads comma, semicolon or tab separated files")
    return best


def _numbers(path: Path, rows: list, header: list, decimal_comma: bool) -> np.ndarray:
    """(N, n_col) floats of the data rows; the first bad cell raises, naming its line and column."""
    n_col = len(header)
    data = np.empty((len(rows), n_col))
    for i, row in enumerate(rows):
        line = i + 2
        if len(row) != n_col:
            raise RecordingError(f"{path}: line {line} has {len(row)} fields, the header has {n_col}")
        for j, cell in enumerate(row):
            try:
                data[i, j] = float(cell)
            except ValueError:
                if decimal_comma and cell.count(",") == 1 and "." not in cell:
                    try:
                        data[i, j] = float(cell.replace(",", "."))
                        continue
                    except ValueError:
                        pass
                raise RecordingError(f"{path}: line {line}, column {header[j]!r}: {cell!r} is not a number") from None
    return data


def read_sidecar(path: str | Path) -> dict:
    """A recording's sidecar ``<name>.json``: a JSON object whose fields pneumasim reads
    (:data:`SIDECAR_FIELDS`) have the right types; raises :class:`RecordingError` naming the
    file and field."""
    path = Path(path)
    try:
        meta = json.loads(path.read_text(encoding="utf-8-sig"))
    except UnicodeDecodeError:
        raise RecordingError(f"{path}: sidecar is not UTF-8 text") from None
    except json.JSONDecodeError as e:
        raise RecordingError(f"{path}: sidecar is not valid JSON: {e}") from None
    if not isinstance(meta, dict):
        raise RecordingError(f"{path}: sidecar must be a JSON object {{\"field\": value, ...}}, "
                             f"got a JSON {_json_kind(meta)}")
    return check_metadata(meta, f"{path}: sidecar")


def check_metadata(meta: dict, where: str) -> dict:
    """``meta`` (a sidecar's, or a Parquet file's) with the fields pneumasim reads
    (:data:`SIDECAR_FIELDS`) checked for their types; RecordingError naming ``where`` and the field."""
    for name, (kind, expected) in SIDECAR_FIELDS.items():
        if name not in meta or meta[name] is None:
            continue
        v = meta[name]
        if kind == "positive":
            ok = (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0)
        else:
            ok = isinstance(v, kind)
        if not ok:
            raise RecordingError(f"{where} field {name!r} must be {expected}, got {json.dumps(v)}")
    return meta


def _json_kind(value) -> str:
    return {list: "array", str: "string", bool: "boolean", int: "number", float: "number",
            type(None): "null"}.get(type(value), type(value).__name__)


def validate(rec: Recording, joint_names, actuator_names, *, need_commands: bool = True,
             need_pressures: bool = True, model_name: str | None = None) -> list[str]:
    """Check a recording against a model's names; raise on errors, warn on oddities.

    Returns the list of warnings issued (also emitted as :class:`RecordingWarning`).
    """
    src = rec.source
    said = []

    def warn(msg):
        said.append(msg)
        warnings.warn(msg, RecordingWarning, stacklevel=3)

    if model_name and rec.meta.get("model") not in (None, model_name):
        raise RecordingError(f"{src}: recorded with model {rec.meta['model']!r} (sidecar), "
                             f"but checked against {model_name!r}")
    joints, acts = set(joint_names), set(actuator_names)
    for col in rec.columns:
        prefix, _, name = col.partition(".")
        if prefix in JOINT_PREFIXES and name and name not in joints:
            raise RecordingError(f"{src}: column {col!r} names unknown joint {name!r}; joints: {', '.join(joint_names)}")
        if prefix in ACTUATOR_PREFIXES and name and name not in acts:
            raise RecordingError(f"{src}: column {col!r} names unknown actuator {name!r}; actuators: {', '.join(actuator_names)}")
    missing_q = [f"q.{j}" for j in joint_names if f"q.{j}" not in rec]
    if missing_q:
        raise RecordingError(f"{src}: missing joint column(s) {', '.join(missing_q)}")
    for a in actuator_names:
        if need_commands and f"i.{a}" not in rec:
            miss = [c for c in (f"u_a.{a}", f"u_b.{a}") if c not in rec]
            if miss:
                raise RecordingError(f"{src}: missing command column(s) {', '.join(miss)}: the doctor and "
                                     "replays need the valve commands")
        if need_pressures:
            miss = [c for c in (f"p_a.{a}", f"p_b.{a}") if c not in rec]
            if miss:
                raise RecordingError(f"{src}: missing pressure column(s) {', '.join(miss)}")
    for col, v in rec.columns.items():
        prefix = col.split(".", 1)[0]
        if prefix in ("p_a", "p_b"):
            if np.all(v < 1.0e5):
                warn(f"{src}: column {col!r} stays below 1 bar (max {v.max():.4g} Pa): gauge pressure? "
                     "pneumasim expects absolute pressures in Pa")
            if np.all(v < 50.0):
                raise RecordingError(f"{src}: column {col!r} is at most {v.max():.4g}: looks like bar, "
                                     "not Pa (absolute pressures in Pa expected)")
        if prefix in ("u_a", "u_b") and (v.min() < -0.5 or v.max() > 10.5):
            warn(f"{src}: column {col!r} spans {v.min():.3g}..{v.max():.3g} V, outside 0-10 V")
        if prefix == "q" and np.max(np.abs(v)) > 2 * math.pi:
            warn(f"{src}: column {col!r} reaches {np.max(np.abs(v)):.4g}: degrees? angles must be in rad")
    # saturated sensors: many identical values at the extreme
    for col, v in rec.columns.items():
        if col.split(".", 1)[0] in ("q", "p_a", "p_b") and v.size > 20:
            for ext in (v.max(), v.min()):
                share = np.mean(v == ext)
                if share > 0.05 and np.ptp(v) > 0:
                    warn(f"{src}: column {col!r} sits at {ext:.6g} in {share:.0%} of rows: saturated sensor?")
    gaps = np.diff(rec.time)
    med = np.median(gaps)
    if np.any(gaps > 3 * med):
        i = int(np.argmax(gaps > 3 * med))
        warn(f"{src}: gap in time of {gaps[i]:.3g} s after t = {rec.time[i]:.3f} s (median step {med:.3g} s)")
    return said
