"""ROS bags as recordings: ROS 1, ROS 2 sqlite3 and MCAP bags written here from a recording read
back equal; topics at other rates are resampled as documented (commands held, sensors linear or
period means); a bad bag or map gets an error naming the bag, topic or map field."""
import shutil
from pathlib import Path

import numpy as np
import pytest

from pneumatics.errors import ConfigError, RecordingError
from pneumatics.formats.by_suffix import read_recording, write_recording
from pneumatics.formats.rosbag import is_ros_bag, read_bag
from pneumatics.formats.rosbag_map import ros_map
from pneumatics.importer import load_map, shipped_maps
from pneumatics.recording import RecordingWarning, validate
from test_formats_parquet import ACTS, JOINTS, arm2_like

NS = 1_000_000_000
START_NS = 1_764_000_000 * NS  # bags carry wall-clock times; the recording starts at 0


def with_reference(rec):
    rec.columns["ref.shoulder"] = np.round(rec["q.shoulder"], 1)  # a stepped, held setpoint
    rec.columns["ref.elbow"] = np.round(rec["q.elbow"], 1)
    return rec


def assert_same(back, rec):
    assert list(back.columns) == list(rec.columns)
    np.testing.assert_array_equal(back.time, rec.time - rec.time[0])
    for name in rec.columns:
        np.testing.assert_array_equal(back[name], rec[name], err_msg=name)


def test_shipped_ros_map_is_valid_and_names_every_arm2_channel():
    rmap = ros_map(load_map(shipped_maps()["ros_arm2"]))
    targets = {t for e in rmap.entries for t in e.targets}
    assert targets == {f"q.{j}" for j in JOINTS} | {f"ref.{j}" for j in JOINTS} | \
        {f"{c}.{a}" for a in ACTS for c in ("p_a", "p_b", "u_a", "u_b")}
    assert rmap.rate_hz == 100.0 and rmap.meta["model"] == "arm2"


@pytest.mark.parametrize("suffix", [".bag", ".db3", ".mcap"])
def test_bag_written_from_a_recording_reads_back_equal(tmp_path, suffix):
    rec = with_reference(arm2_like(n=200))
    made = write_recording(rec, tmp_path / f"run{suffix}", "ros_arm2")
    assert is_ros_bag(made)
    back = read_recording(made, "ros_arm2")  # same rate, messages on the grid: exact
    assert_same(back, rec)
    assert back.meta["model"] == "arm2" and back.meta["daq_averaging"] is True
    assert validate(back, JOINTS, ACTS, model_name="arm2") == []
    if suffix != ".bag":  # one storage file of the folder, and the same file on its own
        storage = made / f"run{suffix}"
        assert_same(read_bag(storage, "ros_arm2"), rec)
        lone = tmp_path / "lone" / f"alone{suffix}"
        lone.parent.mkdir()
        shutil.copy(storage, lone)
        assert_same(read_bag(lone, "ros_arm2"), rec)


def test_bag_start_time_goes_to_the_metadata(tmp_path):
    rec = arm2_like(n=50)
    rec.time += 12.5  # a recording that does not start at 0
    made = write_recording(with_reference(rec), tmp_path / "late.mcap", "ros_arm2")
    back = read_recording(made, "ros_arm2")
    assert back.time[0] == 0.0 and back.meta["ros_start_ns"] == 0
    np.testing.assert_allclose(back.time, rec.time - 12.5, atol=1e-12)


# -- bags made message by message: other rates, other clocks, bad content ----------------------
def write_messages(path: Path, topics: dict):
    """topics: name -> (msgtype, [(receive ns, header ns or None, field dict)]); ROS 2 unless .bag."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    ros1 = path.suffix == ".bag"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    writer = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP)
    types = store.types
    with writer:
        for topic, (msgtype, messages) in topics.items():
            con = writer.add_connection(topic, msgtype, typestore=store)
            for receive_ns, header_ns, fields in messages:
                if header_ns is not None:
                    stamp = types["builtin_interfaces/msg/Time"](sec=header_ns // NS, nanosec=header_ns % NS)
                    extra = {"seq": 0} if ros1 else {}
                    fields = {"header": types["std_msgs/msg/Header"](stamp=stamp, frame_id="", **extra), **fields}
                msg = types[msgtype](**fields)
                serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
                writer.write(con, receive_ns, serialize(msg, msgtype))
    return path


def joint_state(q_shoulder, q_elbow):
    """Names in the other order than the map's, velocities present."""
    return {"name": ["elbow", "shoulder"], "position": np.array([q_elbow, q_shoulder]),
            "velocity": np.array([0.0, 0.0]), "effort": np.zeros(0)}


def multi_array(values):
    from rosbags.typesys import Stores, get_typestore

    t = get_typestore(Stores.ROS2_HUMBLE).types
    dim = t["std_msgs/msg/MultiArrayDimension"](label="", size=len(values), stride=len(values))
    return {"layout": t["std_msgs/msg/MultiArrayLayout"](dim=[dim], data_offset=0), "data": np.array(values, float)}


W = 2 * np.pi * 1.5  # the shoulder's sine [rad/s]


def multirate_topics(seconds=2.0, jitter_seed=5):
    """/js ~1 kHz with jitter, /pa and /pb 250 Hz, /u 20 Hz (Float64), /cmd 50 Hz (3-element array)."""
    rng = np.random.default_rng(jitter_seed)
    n = int(seconds * 1000) + 1
    js_ns = START_NS + np.arange(n) * 1_000_000 + rng.integers(0, 300_000, n)
    js_ns[0] = START_NS
    js = [(int(n), int(n) - 5_000_000, joint_state(np.sin(W * (n - START_NS) / NS), 0.5 * ((n - START_NS) / NS) ** 2))
          for n in js_ns]
    p_ns = START_NS + np.arange(int(seconds * 250) + 1) * 4_000_000
    pa = [(int(n), int(n), {"fluid_pressure": 4e5 + 1e4 * (n - START_NS) / NS, "variance": 0.0}) for n in p_ns]
    pb = [(int(n), int(n), {"fluid_pressure": 3e5, "variance": 0.0}) for n in p_ns]
    u = [(START_NS + k * 50_000_000, None, {"data": float(k)}) for k in range(int(seconds * 20) + 1)]
    cmd = [(START_NS + k * 20_000_000, None, multi_array([1000.0 * k, -1.0, 2000.0 * k]))
           for k in range(int(seconds * 50) + 1)]
    return {"/js": ("sensor_msgs/msg/JointState", js), "/pa": ("sensor_msgs/msg/FluidPressure", pa),
            "/pb": ("sensor_msgs/msg/FluidPressure", pb), "/u": ("std_msgs/msg/Float64", u),
            "/cmd": ("std_msgs/msg/Float64MultiArray", cmd)}


MAP = """
[source]
atmosphere_pa = 100000.0
[meta]
model = "arm2"
[ros]
rate_hz = 100.0
sensors = "{sensors}"
[[ros.joint_state]]
topic = "/js"
fields = ["position"]
joints = {{ shoulder = "shoulder", elbow = "elbow" }}
{js_extra}
[[ros.pressure]]
topic = "/pa"
target = "p_a.shoulder"
gauge = false
[[ros.pressure]]
topic = "/pb"
target = "p_b.shoulder"
gauge = true
[[ros.command]]
topic = "/u"
targets = ["u_a.shoulder"]
[[ros.command]]
topic = "/cmd"
targets = ["u_a.elbow", "", "u_b.elbow"]
unit = "mV"
"""


def a_map(tmp_path, sensors="linear", js_extra="", edit=None, name="m.toml"):
    text = MAP.format(sensors=sensors, js_extra=js_extra)
    if edit:
        assert edit[0] in text
        text = text.replace(*edit)
    (tmp_path / name).write_text(text)
    return tmp_path / name


def test_topics_at_other_rates_are_held_or_interpolated(tmp_path):
    bag = write_messages(tmp_path / "multi", multirate_topics())
    rec = read_bag(bag, a_map(tmp_path))
    t = rec.time
    assert t[0] == 0.0 and t[-1] == pytest.approx(2.0) and np.allclose(np.diff(t), 0.01)
    # commands: zero-order hold, exactly the last message sent (20 Hz and 50 Hz, mV -> V)
    np.testing.assert_array_equal(rec["u_a.shoulder"], np.floor(t * 20 + 1e-9))
    np.testing.assert_allclose(rec["u_a.elbow"], np.floor(t * 50 + 1e-9), rtol=1e-12)
    np.testing.assert_allclose(rec["u_b.elbow"], 2 * np.floor(t * 50 + 1e-9), rtol=1e-12)
    # sensors: linear; exact for a ramp, within h^2 max|q''| / 8 for the sine (h <= 1.3 ms)
    np.testing.assert_allclose(rec["p_a.shoulder"], 4e5 + 1e4 * t, rtol=1e-12)
    np.testing.assert_allclose(rec["q.elbow"], 0.5 * t ** 2, atol=(1.3e-3) ** 2 / 8 * 1.0 + 1e-12)
    assert np.max(np.abs(rec["q.shoulder"] - np.sin(W * t))) <= (1.3e-3) ** 2 / 8 * W ** 2
    # gauge FluidPressure + the map's atmosphere; absolute left alone
    np.testing.assert_array_equal(rec["p_b.shoulder"], 3e5 + 1e5)
    assert list(rec.columns) == ["q.shoulder", "q.elbow", "p_a.shoulder", "p_b.shoulder",
                                 "u_a.shoulder", "u_a.elbow", "u_b.elbow"]
    assert rec.meta["daq_averaging"] is False  # instantaneous samples, interpolated
    assert rec.meta["ros_start_ns"] == START_NS


def test_period_mean_is_the_daq_average_over_the_period_ending_at_each_row(tmp_path):
    bag = write_messages(tmp_path / "multi", multirate_topics())
    rec = read_bag(bag, a_map(tmp_path, sensors="period_mean"))
    T = 0.01
    t_abs = rec.time + T  # the first row needs a full period of data: the grid starts 10 ms in
    exact = (np.cos(W * (t_abs - T)) - np.cos(W * t_abs)) / (W * T)  # mean of sin over (t - T, t]
    assert np.max(np.abs(rec["q.shoulder"] - exact)) <= (1.3e-3) ** 2 / 8 * W ** 2
    assert np.max(np.abs(rec["q.shoulder"] - np.sin(W * t_abs))) > 0.03  # the half-period lag is real
    np.testing.assert_allclose(rec["p_a.shoulder"], 4e5 + 1e4 * (t_abs - T / 2), rtol=1e-12)
    assert rec.meta["daq_averaging"] is True
    np.testing.assert_array_equal(rec["u_a.shoulder"], np.floor(t_abs * 20 + 1e-9))  # commands still held


def test_header_stamps_give_the_sensor_clock(tmp_path):
    bag = write_messages(tmp_path / "multi", multirate_topics())
    rec = read_bag(bag, a_map(tmp_path, js_extra='stamp = "header"'))
    # /js is stamped 5 ms before it was received: read by header.stamp the sine is 5 ms ahead of
    # the receive-time reading, and the grid starts where every topic (by its clock) has data
    rec_rx = read_bag(bag, a_map(tmp_path, name="rx.toml"))
    assert rec.meta["ros_start_ns"] == rec_rx.meta["ros_start_ns"] == START_NS
    bound = (1.3e-3) ** 2 / 8 * W ** 2
    np.testing.assert_allclose(rec_rx["q.shoulder"], np.sin(W * rec_rx.time), atol=bound)
    np.testing.assert_allclose(rec["q.shoulder"][:-1], np.sin(W * (rec.time[:-1] + 0.005)), atol=bound)
    u_by_header = ('targets = ["u_a.shoulder"]', 'targets = ["u_a.shoulder"]\nstamp = "header"')
    with pytest.raises(RecordingError, match="topic '/u' has no header.*stamp = \"receive\""):
        read_bag(bag, a_map(tmp_path, edit=u_by_header))


def test_ros1_bag_with_names_in_another_order(tmp_path):
    topics = multirate_topics(seconds=0.5)
    for name in ("/u", "/cmd"):  # sensors only: multi_array builds its layout with ROS 2 classes
        topics.pop(name)
    bag = write_messages(tmp_path / "multi.bag", topics)
    text = MAP.format(sensors="linear", js_extra="").split("[[ros.command]]")[0]  # no command topics
    (tmp_path / "ros1.toml").write_text(text)
    rec = read_bag(bag, tmp_path / "ros1.toml")
    assert np.max(np.abs(rec["q.shoulder"] - np.sin(W * rec.time))) <= (1.3e-3) ** 2 / 8 * W ** 2
    np.testing.assert_allclose(rec["q.elbow"], 0.5 * rec.time ** 2, atol=1e-6)


def test_slow_sensor_topic_is_warned_about(tmp_path):
    topics = multirate_topics(seconds=1.0)
    msgtype, messages = topics["/pa"]
    topics["/pa"] = (msgtype, messages[::10])  # 25 Hz under a 100 Hz map
    bag = write_messages(tmp_path / "slow", topics)
    with pytest.warns(RecordingWarning, match="topic '/pa' publishes at ~25 Hz, below the map's 100 Hz"):
        read_bag(bag, a_map(tmp_path))


def replace(topics, topic, i, fields):
    """Message i of topic with other fields, same times."""
    receive_ns, header_ns, _ = topics[topic][1][i]
    topics[topic][1][i] = (receive_ns, header_ns, fields)


@pytest.mark.parametrize("change, match", [
    (lambda t: t.pop("/pb"), "no topic '/pb' \\(map m.toml\\); topics in the bag: /cmd, /js, /pa, /u"),
    (lambda t: t.update({"/pa": t["/js"]}), "topic '/pa' carries sensor_msgs/msg/JointState, the map's entry "
                                            "for it reads sensor_msgs/msg/FluidPressure"),
    (lambda t: replace(t, "/js", 3, joint_state(float("nan"), 0.0)),
     "topic '/js', channel 'q.shoulder' is nan at 0.003.* s into the topic"),
    (lambda t: replace(t, "/js", 2, {**joint_state(0, 0), "name": ["elbow", "wrist"]}),
     "topic '/js', message 3: no joint\\(s\\) 'shoulder' in name; the message names 'elbow', 'wrist'"),
    (lambda t: replace(t, "/cmd", 0, multi_array([1.0, 2.0])),
     "topic '/cmd', message 1: 2 value\\(s\\) in data, the map names 3 target\\(s\\)"),
])
def test_bad_bag_content_names_bag_and_topic(tmp_path, change, match):
    topics = multirate_topics(seconds=0.2)
    change(topics)
    bag = write_messages(tmp_path / "bad", topics)
    with pytest.raises(RecordingError, match=f"^{bag}: {match}"):
        read_bag(bag, a_map(tmp_path))


def test_velocity_field_must_be_filled_if_the_map_reads_it(tmp_path):
    topics = multirate_topics(seconds=0.2)
    for i, (rx, hd, fields) in enumerate(topics["/js"][1]):
        topics["/js"][1][i] = (rx, hd, {**fields, "velocity": np.zeros(0)})
    bag = write_messages(tmp_path / "novel", topics)
    path = a_map(tmp_path, edit=('fields = ["position"]', 'fields = ["position", "velocity"]'))
    with pytest.raises(RecordingError, match="topic '/js', message 1: velocity has 0 value\\(s\\) for 2 joint name"):
        read_bag(bag, path)


@pytest.mark.parametrize("edit, match", [
    (("gauge = true\n", ""), "ros.pressure #2: gauge = None: state whether the topic publishes gauge"),
    (("atmosphere_pa = 100000.0\n", ""), "ros.pressure #2: gauge pressure: state source.atmosphere_pa"),
    (("rate_hz = 100.0\n", ""), "ros.rate_hz = None: expected the recording's rate in Hz"),
    (('unit = "mV"', 'unit = "rad"'), "ros.command #2: target 'u_a.elbow' needs a voltage unit, got 'rad'"),
    (('target = "p_b.shoulder"', 'target = "p_a.shoulder"'),
     "channel 'p_a.shoulder' comes from both '/pa' and '/pb'"),
    (('target = "p_a.shoulder"', 'target = "q.shoulder"'), "ros.pressure #1: target = 'q.shoulder': a FluidPressure"),
    (('topic = "/u"', 'topic = "/u"\nperiod = 2'), "ros.command #1: unknown field\\(s\\) \\['period'\\]"),
    (('sensors = "linear"', 'sensors = "cubic"'), "ros.sensors = 'cubic': expected one of 'linear', 'period_mean'"),
    (('fields = ["position"]', 'fields = ["pos"]'), "ros.joint_state #1: fields = \\['pos'\\]: expected a list of"),
])
def test_bad_map_names_file_and_field(tmp_path, edit, match):
    bag = write_messages(tmp_path / "ok", multirate_topics(seconds=0.2))
    path = a_map(tmp_path, edit=edit)
    with pytest.raises(ConfigError, match=f"^{path}: {match}"):
        read_bag(bag, path)


def test_wrong_pairings_of_file_and_map_are_explained(tmp_path):
    bag = write_messages(tmp_path / "ok", multirate_topics(seconds=0.2))
    with pytest.raises(RecordingError, match="a ROS bag needs an import map"):
        read_recording(bag)
    with pytest.raises(ConfigError, match="zillen_chamber.toml: no \\[ros\\] section"):
        read_recording(bag, "zillen_chamber")
    (tmp_path / "junk.mcap").write_text("not a bag")
    with pytest.raises(RecordingError, match="junk.mcap: not a readable ROS bag"):
        read_recording(tmp_path / "junk.mcap", a_map(tmp_path))
    with pytest.raises(RecordingError, match="gone.bag: ROS bag not found"):
        read_recording(tmp_path / "gone.bag", a_map(tmp_path))


def test_pneumasim_import_turns_a_bag_into_csv_or_parquet(tmp_path, capsys):
    from pneumasim.cli import main as cli_main

    rec = with_reference(arm2_like(n=120))
    bag = write_recording(rec, tmp_path / "lab.db3", "ros_arm2")
    for out in ("run.parquet", "run.csv"):
        cli_main(["import", str(bag), "--map", "ros_arm2", "--out", str(tmp_path / out), "--meta", "operator_note=x"])
        back = read_recording(tmp_path / out)
        np.testing.assert_allclose(back["p_b.elbow"], rec["p_b.elbow"], rtol=1e-6)
        assert back.meta["model"] == "arm2" and back.meta["operator_note"] == "x"
        assert back.meta["imported_from"] == str(bag)
    assert "120 rows" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="pneumasim: error: .*ros_arm2.toml: no \\[\\[column\\]\\] entries: this map "
                                         "reads ROS bags"):
        cli_main(["import", str(tmp_path / "run.csv"), "--map", "ros_arm2", "--out", str(tmp_path / "x.csv")])
    with pytest.raises(SystemExit, match="pneumasim: error: .*lab: a ROS bag needs an import map"):
        cli_main(["doctor", "--model", "arm2", str(bag), "--out", str(tmp_path / "doc")])
