"""Read or write a recording in the format its file name says.

``.csv`` (DESIGN.md's format, sidecar ``.json``), ``.parquet`` (:mod:`.parquet`), and ROS bags
(:mod:`.rosbag`: ``.bag``, ``.db3``, ``.mcap`` or a ROS 2 bag folder), which need an import
map with a ``[ros]`` section.  Every reader ends in a :class:`~pneumatics.recording.Recording`
that has passed the same row checks (numbers, finite, strictly increasing time), so
:func:`pneumatics.recording.validate` and the doctor treat them alike.
"""
from __future__ import annotations

from pathlib import Path

from ..errors import RecordingError
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
