"""Read or write a recording in the format its file name says.

``.csv`` (DESIGN.md's format, sidecar ``.json``), ``.parquet`` (:mod:`.parquet`), and ROS bags
(:mod:`.rosbag`: ``.bag``, ``.db3``, ``.mcap`` or a ROS 2 bag folder), which need an import
map with a ``[ros]`` section.  Every reader ends in a :class:`~pneumatics.recording.Recording`
that has passed the same row checks (numbers, finite, strictly increasing time), so
:func:`pneumatics.recording.validate` and the doctor treat them alike.
"""
from __future__ import annotations

from pathlib import Path

from ..errors import OutputError, RecordingError
from ..importer import import_file, sidecar_path
from ..io import OutputFiles
from ..recording import Recording, read_csv, read_parquet
from .rosbag import is_ros_bag, read_bag
from .rosbag_write import write_bag

READERS = {".csv": read_csv, ".parquet": read_parquet}
FORMATS = ".csv, .parquet, or a ROS bag (.bag, .db3, .mcap, ROS 2 bag folder) with a map"


def read_recording(path: str | Path, mapping=None) -> Recording:
    """The recording in ``path``; ``mapping`` (an import map with ``[ros]``) for ROS bags."""
    path = Path(path)
    if is_ros_bag(path):
        if mapping is None:
            raise RecordingError(f"{path}: a ROS bag needs an import map saying which topic is which "
                                 "column (--map MAP.toml with a [ros] section; docs/recordings.md)")
        return read_bag(path, mapping)
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        raise RecordingError(f"{path}: unknown recording format {path.suffix or '(no suffix)'!r}; "
                             f"expected {FORMATS}")
    if mapping is not None:
        raise RecordingError(f"{path}: a map is only for ROS bags; a {path.suffix} recording is read as it is "
                             "(convert a lab log first with pneumasim import)")
    return reader(path)


def write_recording(rec: Recording, path: str | Path, mapping=None) -> Path:
    """Write ``rec`` as ``path``'s suffix says; ROS bags need ``mapping``.  Returns what was written."""
    path = Path(path)
    if path.suffix.lower() in (".bag", ".db3", ".mcap"):
        if mapping is None:
            raise RecordingError(f"{path}: writing a ROS bag needs an import map with a [ros] section")
        return write_bag(rec, path, mapping)
    rec.write(path)
    return path


def import_recording(src, mapping, out, meta: dict | None = None) -> Recording:
    """Import ``src`` (a lab log, or a ROS bag through the map's ``[ros]`` section) and write
    ``out`` by its suffix: ``.csv`` with its sidecar ``REC.json`` (both or neither), or
    ``.parquet`` (metadata inside).

    Checked before reading: ``out`` is not ``src``, the sidecar is not ``src``, ``out`` is not
    a ``.json`` name (the sidecar would fall on it) and everything can be written."""
    out = Path(out)
    if out.suffix.lower() == ".json":
        raise OutputError(f"--out {out}: a recording is a CSV file and its metadata goes to a sidecar "
                          f"of the same name with .json; give e.g. --out {out.with_suffix('.csv')}")
    if out.suffix.lower() not in (".csv", ".parquet"):
        raise OutputError(f"--out {out}: a recording is written as .csv (with a .json sidecar) or .parquet")
    read = read_bag if is_ros_bag(src) else import_file
    targets = (out, sidecar_path(out)) if out.suffix.lower() == ".csv" else (out,)
    if len(targets) > 1 and targets[1].resolve() == Path(src).expanduser().resolve():
        raise OutputError(f"--out {out}: its sidecar {targets[1]} would overwrite the input {src}; give --out another name")
    with OutputFiles(*targets, inputs=[src]) as files:
        rec = read(src, mapping, meta)
        if out.suffix.lower() == ".csv":
            rec.to_csv(files.file(out), sidecar=files.file(targets[1]))
        else:
            rec.to_parquet(files.file(out))
    return rec
