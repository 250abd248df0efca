"""Write a recording as a ROS bag through an import map's ``[ros]`` section (the inverse of
:func:`pneumatics.formats.rosbag.read_bag`): to hand pneumasim's runs to ROS tools, and to
test the bag readers on bags made from known recordings.

Row k becomes one message per mapped topic, stamped (bag time and ``header.stamp``)
``start_ns + round((time[k] - time[0]) 1e9)``: sensor_msgs/JointState, sensor_msgs/FluidPressure
(gauge if the map says so) and, for command topics, std_msgs/Float64 (one target) or
std_msgs/Float64MultiArray (several; an unused ``""`` element is written as 0).
``.bag`` writes a ROS 1 bag file; ``.db3`` / ``.mcap`` a ROS 2 bag folder (the path without
its suffix) holding ``metadata.yaml`` and the one storage file ``<stem>.db3`` / ``<stem>.mcap``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import RecordingError
from ..importer import ImportMap, UNITS, load_map
from ..recording import Recording
from .rosbag_map import JOINT_FIELDS, CommandTopic, JointStateTopic, PressureTopic, ros_map


def write_bag(rec: Recording, path: str | Path, mapping: ImportMap | str | Path, start_ns: int = 0) -> Path:
    """Write ``rec`` as a bag at ``path`` (.bag, .db3 or .mcap); returns the file or folder made."""
    path = Path(path)
    rmap = ros_map(mapping if isinstance(mapping, ImportMap) else load_map(mapping))
    suffix = path.suffix.lower()
    if suffix not in (".bag", ".db3", ".mcap"):
        raise RecordingError(f"{path}: a ROS bag is written as .bag (ROS 1), .db3 or .mcap (ROS 2)")
    for entry in rmap.entries:
        missing = [t for t in entry.targets if t not in rec]
        if missing:
            raise RecordingError(f"{rec.source}: no column(s) {', '.join(missing)} for topic {entry.topic!r} "
                                 f"of map {Path(rmap.path).name}")
    stamps = start_ns + np.round((rec.time - rec.time[0]) * 1e9).astype(np.int64)
    ros1 = suffix == ".bag"
    out = path if ros1 else path.with_suffix("")
    if out.exists():
        raise RecordingError(f"{out}: exists already; a bag is never overwritten")
    with _writer(out, suffix) as (writer, store):
        serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
        cons = [(entry, _msgtype(entry)) for entry in rmap.entries]
        cons = [(e, t, writer.add_connection(e.topic, t, typestore=store)) for e, t in cons]
        for k, stamp in enumerate(stamps):  # in time order, as a recorder writes: readers merge by time
            for entry, msgtype, con in cons:
                msg = _message(store, entry, rec, k, int(stamp), rmap.atmosphere_pa)
                writer.write(con, int(stamp), serialize(msg, msgtype))
    return out


class _writer:
    """The rosbags writer and its type store for a suffix, as a context manager."""

    def __init__(self, out: Path, suffix: str):
        from rosbags.rosbag1 import Writer as Writer1
        from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
        from rosbags.typesys import Stores, get_typestore

        if suffix == ".bag":
            self.writer, self.store = Writer1(out), get_typestore(Stores.ROS1_NOETIC)
        else:
            plugin = StoragePlugin.MCAP if suffix == ".mcap" else StoragePlugin.SQLITE3
            self.writer = Writer2(out, version=Writer2.VERSION_LATEST, storage_plugin=plugin)
            self.store = get_typestore(Stores.ROS2_HUMBLE)

    def __enter__(self):
        self.writer.open()
        return self.writer, self.store

    def __exit__(self, *exc):
        self.writer.close()
        return False


def _msgtype(entry) -> str:
    if isinstance(entry, JointStateTopic):
        return "sensor_msgs/msg/JointState"
    if isinstance(entry, PressureTopic):
        return "sensor_msgs/msg/FluidPressure"
    return "std_msgs/msg/Float64" if len(entry.targets_by_index) == 1 else "std_msgs/msg/Float64MultiArray"


def _message(store, entry, rec: Recording, k: int, stamp_ns: int, atmosphere_pa):
    types = store.types
    if isinstance(entry, CommandTopic):
        factor = entry.scale * UNITS[entry.unit][1]
        data = np.array([rec[t][k] / factor if t else 0.0 for t in entry.targets_by_index])
        if len(data) == 1:
            return types["std_msgs/msg/Float64"](data=float(data[0]))
        dim = types["std_msgs/msg/MultiArrayDimension"](label="", size=len(data), stride=len(data))
        layout = types["std_msgs/msg/MultiArrayLayout"](dim=[dim], data_offset=0)
        return types["std_msgs/msg/Float64MultiArray"](layout=layout, data=data)
    header = _header(types, stamp_ns, k)
    if isinstance(entry, PressureTopic):
        p = rec[entry.target][k] - (atmosphere_pa if entry.gauge else 0.0)
        return types["sensor_msgs/msg/FluidPressure"](header=header, fluid_pressure=float(p), variance=0.0)
    names = list(entry.joints.values())
    arrays = {f: np.array([rec[f"{JOINT_FIELDS[f]}.{j}"][k] for j in entry.joints]) if f in entry.fields
              else np.zeros(0) for f in JOINT_FIELDS}
    return types["sensor_msgs/msg/JointState"](header=header, name=names, **arrays)


def _header(types, stamp_ns: int, seq: int):
    stamp = types["builtin_interfaces/msg/Time"](sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
    fields = types["std_msgs/msg/Header"].__dataclass_fields__
    if "seq" in fields:  # ROS 1
        return types["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id="")
    return types["std_msgs/msg/Header"](stamp=stamp, frame_id="")
