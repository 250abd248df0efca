"""The ``[ros]`` section of an import map: which ROS topic and field gives which channel.

The same TOML maps as ``pneumasim import`` (:mod:`pneumatics.importer`); a map for bags has
``[meta]``, optionally ``[source] atmosphere_pa`` (for gauge pressures) and::

    [ros]
    rate_hz = 100.0            # the recording's time base [Hz]
    stamp = "receive"          # message time: "receive" (bag time) or "header" (header.stamp)
    sensors = "linear"         # sensor resampling: "linear" or "period_mean"

    [[ros.joint_state]]        # sensor_msgs/JointState -> q.<joint>, qd.<joint>, tau.<joint>
    topic = "/arm2/joint_states"
    fields = ["position", "velocity"]            # of position, velocity, effort
    joints = { shoulder = "shoulder", elbow = "elbow" }   # recording joint = name in msg.name

    [[ros.pressure]]           # sensor_msgs/FluidPressure [Pa] -> one pressure channel
    topic = "/arm2/shoulder/pressure_a"
    target = "p_a.shoulder"
    gauge = false              # required: is the published pressure gauge (+ atmosphere_pa)?

    [[ros.command]]            # std_msgs/Float64 or Float64MultiArray (Float32 too), held
    topic = "/arm2/valve_command"
    targets = ["u_a.shoulder", "u_b.shoulder"]   # one per element of data; "" skips one
    unit = "V"                 # a unit of pneumatics.importer.UNITS (default V)
    scale = 1.0                # optional factor before the unit conversion

Every entry may override ``stamp``.  Resampling (:mod:`.rosbag`): commands by zero-order
hold, sensors linearly or as the mean over the period ending at each row.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import ConfigError
from ..importer import TARGET_QUANTITY, UNITS, ImportMap, TARGET_PATTERN

JOINT_FIELDS = {"position": "q", "velocity": "qd", "effort": "tau"}
"""sensor_msgs/JointState field -> recording prefix (REP 103 units: rad or m, rad/s or m/s, N m or N)"""
STAMPS = ("receive", "header")
SENSOR_RESAMPLING = ("linear", "period_mean")


@dataclass(frozen=True)
class JointStateTopic:
    topic: str
    joints: dict
    """recording joint -> the name in the message's ``name`` list"""
    fields: tuple
    """of :data:`JOINT_FIELDS`"""
    stamp: str

    @property
    def targets(self) -> list[str]:
        return [f"{JOINT_FIELDS[f]}.{j}" for f in self.fields for j in self.joints]


@dataclass(frozen=True)
class PressureTopic:
    topic: str
    target: str
    """p_a.<actuator> or p_b.<actuator>"""
    gauge: bool
    stamp: str

    @property
    def targets(self) -> list[str]:
        return [self.target]


@dataclass(frozen=True)
class CommandTopic:
    topic: str
    targets_by_index: tuple
    """channel of each element of ``data`` ("" = not used)"""
    unit: str
    scale: float
    stamp: str

    @property
    def targets(self) -> list[str]:
        return [t for t in self.targets_by_index if t]

    def to_si(self, values):
        """Message values in SI (the unit's factor; commands have no gauge units)."""
        return values * self.scale * UNITS[self.unit][1]


@dataclass(frozen=True)
class RosMap:
    path: str
    rate_hz: float
    sensors: str
    """"linear" or "period_mean" (:data:`SENSOR_RESAMPLING`)"""
    atmosphere_pa: float | None
    entries: tuple
    """JointStateTopic, PressureTopic and CommandTopic entries, in map order"""
    meta: dict

    def entry(self, topic: str):
        return next(e for e in self.entries if e.topic == topic)


def ros_map(imap: ImportMap) -> RosMap:
    """Check ``imap``'s ``[ros]`` section; ConfigError naming the map file and field."""
    where = imap.path
    ros = imap.ros
    if ros is None:
        raise ConfigError(f"{where}: no [ros] section: this map reads text logs, not ROS bags "
                          "(see pneumatics/formats/rosbag_map.py for the [ros] format)")
    _known(ros, {"rate_hz", "stamp", "sensors", "joint_state", "pressure", "command"}, f"{where}: [ros]")
    rate = ros.get("rate_hz")
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 < rate <= 1e5:
        raise ConfigError(f"{where}: ros.rate_hz = {rate!r}: expected the recording's rate in Hz (0-100000)")
    stamp = _choice(ros, "stamp", STAMPS, "receive", f"{where}: ros")
    sensors = _choice(ros, "sensors", SENSOR_RESAMPLING, "linear", f"{where}: ros")
    entries = []
    for kind, parse in (("joint_state", _joint_state), ("pressure", _pressure), ("command", _command)):
        tables = ros.get(kind, [])
        if not isinstance(tables, list):
            raise ConfigError(f"{where}: ros.{kind} must be an array of tables ([[ros.{kind}]])")
        for n, table in enumerate(tables, 1):
            entries.append(parse(table, f"{where}: ros.{kind} #{n}", stamp, imap.atmosphere_pa))
    if not entries:
        raise ConfigError(f"{where}: [ros] maps no topic: add [[ros.joint_state]], [[ros.pressure]] "
                          "or [[ros.command]] entries")
    _no_repeats(where, entries)
    return RosMap(where, float(rate), sensors, imap.atmosphere_pa, tuple(entries), dict(imap.meta))


def _joint_state(t, where, stamp, atm) -> JointStateTopic:
    _known(t, {"topic", "joints", "fields", "stamp"}, where)
    joints = t.get("joints")
    if not isinstance(joints, dict) or not joints or not all(isinstance(v, str) for v in joints.values()):
        raise ConfigError(f"{where}: joints = {joints!r}: expected a table recording joint = \"name in the "
                          "message\", e.g. joints = { elbow = \"elbow_joint\" }")
    for j in joints:
        _target(f"q.{j}", where)
    fields = t.get("fields", ["position"])
    if not isinstance(fields, list) or not fields or any(f not in JOINT_FIELDS for f in fields):
        raise ConfigError(f"{where}: fields = {fields!r}: expected a list of {', '.join(JOINT_FIELDS)}")
    return JointStateTopic(_topic(t, where), dict(joints), tuple(fields), _choice(t, "stamp", STAMPS, stamp, where))


def _pressure(t, where, stamp, atm) -> PressureTopic:
    _known(t, {"topic", "target", "gauge", "stamp"}, where)
    target = _target(t.get("target"), where)
    if target.split(".")[0] not in ("p_a", "p_b"):
        raise ConfigError(f"{where}: target = {target!r}: a FluidPressure topic feeds p_a.<actuator> or p_b.<actuator>")
    gauge = t.get("gauge")
    if not isinstance(gauge, bool):
        raise ConfigError(f"{where}: gauge = {gauge!r}: state whether the topic publishes gauge (true) or "
                          "absolute (false) pressure")
    if gauge and atm is None:
        raise ConfigError(f"{where}: gauge pressure: state source.atmosphere_pa (room pressure, Pa) "
                          "to make it absolute")
    return PressureTopic(_topic(t, where), target, gauge, _choice(t, "stamp", STAMPS, stamp, where))


def _command(t, where, stamp, atm) -> CommandTopic:
    _known(t, {"topic", "targets", "unit", "scale", "stamp"}, where)
    targets = t.get("targets")
    if not isinstance(targets, list) or not targets or not all(isinstance(x, str) for x in targets):
        raise ConfigError(f"{where}: targets = {targets!r}: expected a list of channels, one per element "
                          "of the message's data (\"\" skips one), e.g. [\"u_a.elbow\", \"u_b.elbow\"]")
    unit = t.get("unit", "V")
    if unit not in UNITS or UNITS[unit][2]:
        raise ConfigError(f"{where}: unknown unit {unit!r}; valid: "
                          f"{', '.join(u for u, (_, _, gauge) in UNITS.items() if not gauge)}")
    for target in filter(None, targets):
        _target(target, where)
        allowed = TARGET_QUANTITY.get(target.split(".")[0])
        if allowed and UNITS[unit][0] not in allowed:
            raise ConfigError(f"{where}: target {target!r} needs a {' or '.join(allowed)} unit, got {unit!r}")
    scale = t.get("scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not math.isfinite(scale) or scale == 0:
        raise ConfigError(f"{where}: scale = {scale!r}: expected a finite non-zero number")
    return CommandTopic(_topic(t, where), tuple(targets), unit, float(scale),
                        _choice(t, "stamp", STAMPS, stamp, where))


def _known(t, valid: set, where: str):
    if not isinstance(t, dict):
        raise ConfigError(f"{where}: expected a table")
    bad = set(t) - valid
    if bad:
        raise ConfigError(f"{where}: unknown field(s) {sorted(bad)}; valid: {', '.join(sorted(valid))}")


def _topic(t, where) -> str:
    topic = t.get("topic")
    if not isinstance(topic, str) or not topic:
        raise ConfigError(f"{where}: topic = {topic!r}: expected a topic name such as \"/joint_states\"")
    return topic


def _target(target, where) -> str:
    if not isinstance(target, str) or not TARGET_PATTERN.match(target) or target == "time":
        raise ConfigError(f"{where}: target = {target!r}: expected a channel such as 'q.elbow', 'p_a.elbow', "
                          "'u_a.elbow'")
    return target


def _choice(t, key, valid, default, where) -> str:
    value = t.get(key, default)
    if value not in valid:
        raise ConfigError(f"{where}.{key} = {value!r}: expected one of {', '.join(map(repr, valid))}")
    return value


def _no_repeats(where, entries):
    topics, targets = {}, {}
    for e in entries:
        if e.topic in topics:
            raise ConfigError(f"{where}: topic {e.topic!r} is mapped twice; one entry per topic")
        topics[e.topic] = e
        for target in e.targets:
            if target in targets:
                raise ConfigError(f"{where}: channel {target!r} comes from both {targets[target]!r} and {e.topic!r}")
            targets[target] = e.topic
