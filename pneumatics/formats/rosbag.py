"""Read ROS bags into recordings: ROS 1 (``.bag``), ROS 2 sqlite3 (``.db3``) and MCAP (``.mcap``).

An import map's ``[ros]`` section (:mod:`.rosbag_map`) says which topic gives which channel;
the topics (at their own rates) are resampled onto one time base at the map's ``rate_hz``
(:mod:`.resample`): commands by zero-order hold, sensors linearly or as period means.  The
time base runs over the span where every mapped topic has data; ``time`` 0 is its first
instant, whose absolute bag time goes into the metadata as ``ros_start_ns``.

Bags are read with :mod:`rosbags` (pure Python, no ROS install).  A ROS 2 bag is a folder
with ``metadata.yaml``; give the folder, or one ``.db3``/``.mcap`` file of it (then its
folder is read), or a lone ``.mcap``/``.db3`` file without ``metadata.yaml`` (read with the
standard ROS 2 message definitions).  Every problem is a :class:`RecordingError` naming the
bag and the topic; a bad map a :class:`ConfigError` naming the map and field.
"""
from __future__ import annotations

import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import RecordingError
from ..importer import ImportMap, load_map
from ..recording import Recording, RecordingWarning
from . import resample
from .rosbag_map import CommandTopic, JointStateTopic, PressureTopic, RosMap, ros_map

BAG_SUFFIXES = (".bag", ".db3", ".mcap")
MESSAGE_TYPES = {
    JointStateTopic: ("sensor_msgs/msg/JointState",),
    PressureTopic: ("sensor_msgs/msg/FluidPressure",),
    CommandTopic: ("std_msgs/msg/Float64", "std_msgs/msg/Float32", "std_msgs/msg/Float64MultiArray",
                   "std_msgs/msg/Float32MultiArray"),
}
"""map entry kind -> the message types it reads (ROS 1 names are normalised to these)"""


def is_ros_bag(path: str | Path) -> bool:
    """A ``.bag``/``.db3``/``.mcap`` file or a ROS 2 bag folder (one with ``metadata.yaml``)."""
    path = Path(path)
    return path.suffix.lower() in BAG_SUFFIXES or (path.is_dir() and (path / "metadata.yaml").is_file())


@dataclass
class TopicSamples:
    """One map entry's messages: (M,) int64 times [ns] and (M, K) values, K = entry.targets."""

    stamps_ns: np.ndarray
    values: np.ndarray


def read_bag(path: str | Path, mapping: ImportMap | str | Path, meta: dict | None = None) -> Recording:
    """Read the bag ``path`` through ``mapping`` (a map with ``[ros]``) into a Recording."""
    path = Path(path)
    rmap = ros_map(mapping if isinstance(mapping, ImportMap) else load_map(mapping))
    samples = read_topics(path, rmap)
    grid_ns = _grid(path, rmap, samples)
    period_s = 1.0 / rmap.rate_hz
    columns = {}
    for entry in rmap.entries:
        s = samples[entry.topic]
        if isinstance(entry, CommandTopic):
            values = resample.zero_order_hold(s.stamps_ns, s.values, grid_ns)
        else:
            _warn_if_sparse(path, entry, s, rmap.rate_hz)
            values = (resample.period_mean(s.stamps_ns, s.values, grid_ns, period_s) if rmap.sensors == "period_mean"
                      else resample.linear(s.stamps_ns, s.values, grid_ns))
        columns.update({target: values[:, k] for k, target in enumerate(entry.targets)})
    full_meta = {"daq_averaging": rmap.sensors == "period_mean", **rmap.meta, "imported_from": str(path),
                 "import_map": rmap.path, "ros_start_ns": int(grid_ns[0]),
                 "ros_resampling": f"{rmap.rate_hz:g} Hz; commands zero-order hold, sensors {rmap.sensors}",
                 **(meta or {})}
    # integer ns / 1e9 is correctly rounded: 10_000_000 ns gives the same float as "0.01"
    return Recording((grid_ns - grid_ns[0]) / 1e9, columns, full_meta, str(path))


def read_topics(path: Path, rmap: RosMap) -> dict[str, TopicSamples]:
    """Every mapped topic's messages, checked: type, names, sizes, finite values, times."""
    raw = {e.topic: ([], []) for e in rmap.entries}
    with open_bag(path) as (connections, messages):
        _check_topics(path, rmap, connections)
        for topic, msgtype, bag_ns, msg in messages([c for c in connections if c[0] in raw]):
            entry = rmap.entry(topic)
            raw[topic][0].append(_stamp(path, entry, bag_ns, msg))
            raw[topic][1].append(_values(path, entry, msg, rmap.atmosphere_pa, len(raw[topic][0])))
    out = {}
    for entry in rmap.entries:
        stamps, values = raw[entry.topic]
        if len(stamps) < 2:
            raise RecordingError(f"{path}: topic {entry.topic!r} has {len(stamps)} message(s); need at least 2")
        out[entry.topic] = _ordered(path, entry, np.array(stamps, dtype=np.int64), np.array(values, dtype=float))
    return out


@contextmanager
def open_bag(path: Path):
    """``(connections, messages)``: connections as (topic, msgtype) pairs with the reader's
    connection object; ``messages(selected)`` yields (topic, msgtype, bag time ns, message)."""
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag2 import ReaderError
    from rosbags.serde import SerdeError
    from rosbags.typesys import TypesysError

    if not path.exists():
        raise RecordingError(f"{path}: ROS bag not found")
    folder = path if path.is_dir() else path.parent
    try:
        if path.suffix.lower() == ".bag" or (folder / "metadata.yaml").is_file():
            with AnyReader([path if path.suffix.lower() == ".bag" else folder]) as reader:
                yield _any_reader_view(reader)
        else:
            with _lone_storage(path) as view:
                yield view
    except (AnyReaderError, ReaderError, SerdeError, TypesysError, FileNotFoundError, KeyError) as e:
        raise RecordingError(f"{path}: not a readable ROS bag ({e})") from None


def _any_reader_view(reader):
    connections = [(c.topic, _normal_type(c.msgtype), c) for c in reader.connections]

    def messages(selected):
        for con, bag_ns, raw in reader.messages(connections=[c[2] for c in selected]):
            yield con.topic, _normal_type(con.msgtype), bag_ns, reader.deserialize(raw, con.msgtype)

    return connections, messages


@contextmanager
def _lone_storage(path: Path):
    """A ``.mcap``/``.db3`` file without its bag folder's ``metadata.yaml``."""
    from rosbags.rosbag2.storage_mcap import McapReader
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader
    from rosbags.typesys import Stores, get_typestore

    storage = (McapReader if path.suffix.lower() == ".mcap" else Sqlite3Reader)(path)
    typestore = get_typestore(Stores.ROS2_HUMBLE)  # JointState, FluidPressure, std_msgs: standard types
    storage.open()
    try:
        connections = [(c.topic, _normal_type(c.msgtype), c) for c in storage.connections]

        def messages(selected):
            for con, bag_ns, raw in storage.messages([c[2] for c in selected]):
                yield con.topic, _normal_type(con.msgtype), bag_ns, typestore.deserialize_cdr(raw, con.msgtype)

        yield connections, messages
    finally:
        storage.close()


def _normal_type(msgtype: str) -> str:
    """``sensor_msgs/JointState`` (ROS 1 style) -> ``sensor_msgs/msg/JointState``."""
    pkg, _, name = msgtype.rpartition("/")
    return msgtype if pkg.endswith("/msg") else f"{pkg}/msg/{name}"


def _check_topics(path: Path, rmap: RosMap, connections):
    have = {}
    for topic, msgtype, _ in connections:
        have.setdefault(topic, msgtype)
    for entry in rmap.entries:
        if entry.topic not in have:
            raise RecordingError(f"{path}: no topic {entry.topic!r} (map {Path(rmap.path).name}); topics in the "
                                 f"bag: {', '.join(sorted(have)) or 'none'}")
        expected = MESSAGE_TYPES[type(entry)]
        if have[entry.topic] not in expected:
            raise RecordingError(f"{path}: topic {entry.topic!r} carries {have[entry.topic]}, the map's "
                                 f"entry for it reads {' or '.join(expected)}")


def _stamp(path: Path, entry, bag_ns: int, msg) -> int:
    if entry.stamp == "receive":
        return int(bag_ns)
    header = getattr(msg, "header", None)
    if header is None:
        raise RecordingError(f"{path}: topic {entry.topic!r} has no header: its messages cannot be "
                             "timed by header.stamp; set stamp = \"receive\" for this entry in the map")
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _values(path: Path, entry, msg, atmosphere_pa, number: int) -> list[float]:
    """One message's values in SI, in ``entry.targets`` order."""
    where = f"{path}: topic {entry.topic!r}, message {number}"
    if isinstance(entry, PressureTopic):
        return [float(msg.fluid_pressure) + (atmosphere_pa if entry.gauge else 0.0)]
    if isinstance(entry, CommandTopic):
        data = np.atleast_1d(np.asarray(msg.data, dtype=float))
        if data.size != len(entry.targets_by_index):
            raise RecordingError(f"{where}: {data.size} value(s) in data, the map names "
                                 f"{len(entry.targets_by_index)} target(s) {list(entry.targets_by_index)}")
        kept = [data[i] for i, target in enumerate(entry.targets_by_index) if target]
        return list(entry.to_si(np.array(kept)))
    index = {name: i for i, name in enumerate(msg.name)}
    missing = [n for n in entry.joints.values() if n not in index]
    if missing:
        raise RecordingError(f"{where}: no joint(s) {', '.join(map(repr, missing))} in name; the message "
                             f"names {', '.join(map(repr, msg.name))}")
    out = []
    for field in entry.fields:
        array = getattr(msg, field)
        if len(array) != len(msg.name):
            raise RecordingError(f"{where}: {field} has {len(array)} value(s) for {len(msg.name)} joint name(s); "
                                 f"the map reads fields {list(entry.fields)}")
        out.extend(float(array[index[n]]) for n in entry.joints.values())
    return out


def _ordered(path: Path, entry, stamps: np.ndarray, values: np.ndarray) -> TopicSamples:
    """Sorted by time (header stamps may arrive out of order); finite; no repeated time."""
    order = np.argsort(stamps, kind="stable")
    stamps, values = stamps[order], values[order]
    bad = ~np.isfinite(values)
    if bad.any():
        i, k = np.argwhere(bad)[0]
        raise RecordingError(f"{path}: topic {entry.topic!r}, channel {entry.targets[k]!r} is {values[i, k]} "
                             f"at {(stamps[i] - stamps[0]) * 1e-9:.6g} s into the topic "
                             f"({int(bad.sum())} non-finite value(s) in all); clean or cut the bag")
    same = np.flatnonzero(np.diff(stamps) == 0)
    if same.size:
        raise RecordingError(f"{path}: topic {entry.topic!r} has two messages stamped {int(stamps[same[0]])} ns "
                             f"({entry.stamp} time): time must be strictly increasing")
    return TopicSamples(stamps, values)


def _grid(path: Path, rmap: RosMap, samples: dict[str, TopicSamples]) -> np.ndarray:
    """The time base: every mapped topic has data over it (a full period for period means)."""
    first = max(samples, key=lambda t: samples[t].stamps_ns[0])
    last = min(samples, key=lambda t: samples[t].stamps_ns[-1])
    start = int(samples[first].stamps_ns[0])
    if rmap.sensors == "period_mean":
        start += int(round(1e9 / rmap.rate_hz))
    grid = resample.time_grid(start, int(samples[last].stamps_ns[-1]), rmap.rate_hz)
    if grid.size < 2:
        raise RecordingError(f"{path}: the topics overlap for less than two rows at {rmap.rate_hz:g} Hz: "
                             f"{first!r} starts at {start} ns, {last!r} ends at {samples[last].stamps_ns[-1]} ns")
    return grid


def _warn_if_sparse(path: Path, entry, s: TopicSamples, rate_hz: float):
    """Both sensor rules interpolate between messages: say so where they are sparse."""
    gap_s, before_ns, median_s = resample.largest_gap(s.stamps_ns)
    if median_s > 1.5 / rate_hz:
        warnings.warn(f"{path}: topic {entry.topic!r} publishes at ~{1 / median_s:.3g} Hz, below the map's "
                      f"{rate_hz:g} Hz: values between its messages are interpolated", RecordingWarning, stacklevel=3)
    elif gap_s > 3 * median_s:
        warnings.warn(f"{path}: topic {entry.topic!r} has a gap of {gap_s:.3g} s after "
                      f"{(before_ns - s.stamps_ns[0]) * 1e-9:.3f} s into the topic (median spacing "
                      f"{median_s:.3g} s): values across it are interpolated", RecordingWarning, stacklevel=3)

