"""Units of c4d_data without a DDS graph: rosbag2 layouts (schema text, QoS, metadata), writer and
reader round trip checked by rosbags, recording windows (pre/post-roll, latched cache, drops),
replay timing."""

from __future__ import annotations

import time
from types import SimpleNamespace

import pytest
import yaml

from c4d_data import msgdef, qos
from c4d_data.bag_reader import Decoders, iter_messages, open_bag
from c4d_data.bag_writer import BagWriter
from c4d_data.recording import IDLE, RECORDING, Recorder, RecorderConfig, TopicInfo
from c4d_data.replay_timing import Clock, ReplayOptions, select_topics

STRING = b"\x00\x01\x00\x00\x03\x00\x00\x00hi\x00"


def test_definition_follows_rosbag2_layout():
    text = msgdef.full_text("geometry_msgs/msg/PoseStamped")
    names = [line for line in text.splitlines() if line.startswith("MSG: ")]
    # depth first, each dependency once, sorted per level, names as written in the .msg files
    assert names == ["MSG: geometry_msgs/Pose", "MSG: geometry_msgs/Point", "MSG: geometry_msgs/Quaternion",
                     "MSG: std_msgs/Header", "MSG: builtin_interfaces/Time"]
    assert "\n" + "=" * 80 + "\nMSG: geometry_msgs/Pose\n" in text
    assert msgdef.dependencies("uint8 X = 1\nGeoPoint[] pts\nstring s  # c\n", "c4d_interfaces") == ["c4d_interfaces/GeoPoint"]
    with pytest.raises(msgdef.DefinitionError, match="not installed"):
        msgdef.full_text("no_such_pkg/msg/Thing")


def test_qos_yaml_is_what_rosbags_parses():
    from rclpy.duration import Duration
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rosbags.rosbag2.metadata import parse_qos

    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         deadline=Duration(nanoseconds=qos.INFINITE_NS))
    d = qos.profile_dict(latched)
    assert d["history"] == "keep_last" and d["durability"] == "transient_local"
    assert d["deadline"] == {"sec": 9223372036, "nsec": 854775807}
    parsed = parse_qos(qos.profiles_yaml([d]))[0]
    assert parsed.reliability.name == "RELIABLE" and parsed.durability.name == "TRANSIENT_LOCAL" and parsed.depth == 1
    best = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    assert qos.request_for_offers([latched, latched]) == (qos.RELIABLE, qos.TRANSIENT_LOCAL)
    assert qos.request_for_offers([latched, best]) == (qos.BEST_EFFORT, qos.VOLATILE)


def test_writer_reader_round_trip(tmp_path):
    from rclpy.qos import QoSProfile
    from rosbags.highlevel import AnyReader

    path = tmp_path / "a.mcap"
    writer = BagWriter(path, custom_data={"k": "v"})
    writer.add_topic("/s", "std_msgs/msg/String", msgdef.full_text("std_msgs/msg/String"),
                     [qos.profile_dict(QoSProfile(depth=10))], "RIHS01_x")
    for k in range(1000):
        writer.write("/s", STRING, 10_000 + k * 1000, 5_000 + k * 1000, k)
    summary = writer.close()
    assert summary.message_count == 1000 and summary.counts == {"/s": 1000}
    bag = open_bag(path)
    assert bag.complete and bag.profile == "ros2" and bag.topics["/s"].type_hash == "RIHS01_x"
    meta = bag.rosbag2
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap" and meta["custom_data"] == {"k": "v"}
    assert meta["topics_with_message_count"][0]["message_count"] == 1000
    assert meta["duration"]["nanoseconds"] == 999_000 and meta["relative_file_paths"] == ["a.mcap"]
    assert yaml.safe_load(bag.topics["/s"].offered_qos)[0]["depth"] == 10
    topic, first = next(iter_messages(bag))
    assert Decoders().decode(topic, first.data).data == "hi" and first.publish_time == 5_000
    with AnyReader([path]) as reader:
        assert [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()][:2] == ["hi", "hi"]


def wait_for(condition, seconds=5.0):
    end = time.monotonic() + seconds
    while time.monotonic() < end and not condition():
        time.sleep(0.01)
    return condition()


def test_recording_windows_latched_cache_and_drops(tmp_path):
    now = {"t": 100 * 10**9}
    rec = Recorder(RecorderConfig(tmp_path, pre_roll_s=1.0, post_roll_s=1.0, max_queue_messages=10**6),
                   clock_ns=lambda: now["t"])
    text = msgdef.full_text("std_msgs/msg/String")
    rec.add_topic(TopicInfo("/a", "std_msgs/msg/String", text, []))
    rec.add_topic(TopicInfo("/latched", "std_msgs/msg/String", text, [], latched=True))
    rec.on_message("/latched", STRING, 10 * 10**9, 10 * 10**9, 7)  # long before the flight
    for k in range(50):  # 0.1 s apart, from t = 95 s to 99.9 s
        rec.on_message("/a", STRING, 95 * 10**9 + k * 10**8, 0, k)
    rec.on_armed(False, 99 * 10**9)
    rec.on_armed(True, 100 * 10**9)
    assert rec.state == RECORDING
    rec.on_message("/a", STRING, 100 * 10**9 + 1, 0, 50)
    rec.on_armed(False, 101 * 10**9)
    rec.on_message("/a", STRING, 101 * 10**9 + 5 * 10**8, 0, 51)  # in the post-roll
    rec.on_message("/a", STRING, 102 * 10**9 + 1, 0, 52)  # after it
    now["t"] = 102 * 10**9 + 2
    rec.poll()
    assert rec.state == IDLE
    assert wait_for(lambda: len(rec.files) == 1)
    bag = open_bag(rec.files[0].path)
    seqs = [(t.name, m.sequence, m.log_time) for t, m in iter_messages(bag)]
    assert [s for name, s, _ in seqs if name == "/a"] == list(range(40, 52))  # 1 s pre-roll .. post-roll
    assert ("/latched", 7, 99 * 10**9) in seqs  # cached latched value at the file start
    rec.shutdown()
    tiny = Recorder(RecorderConfig(tmp_path / "b", max_queue_messages=3))
    tiny.add_topic(TopicInfo("/a", "std_msgs/msg/String", text, []))
    tiny.start("test")
    tiny.running = False
    for k in range(2000):
        tiny.on_message("/a", STRING, time.time_ns(), 0, k)
    assert tiny.dropped > 0 and tiny.status()["dropped"] == tiny.dropped
    tiny.shutdown()


def test_replay_timing_and_selection():
    clock = Clock(first_log_ns=1_000, wall_start_ns=50_000, rate=2.0)
    assert clock.due(1_000) == 50_000 and clock.due(3_000) == 51_000 and clock.log_time(51_000) == 3_000
    names = ["/rosout", "/sensors/imu", "/sensors/gps", "/vehicle/status"]
    assert select_topics(names, ["^/sensors"], ["gps"]) == ["/sensors/imu"]
    assert select_topics(names, [], ["^/rosout$"]) == ["/sensors/gps", "/sensors/imu", "/vehicle/status"]
    with pytest.raises(ValueError, match="rate"):
        ReplayOptions(rate=0).validate()
    with pytest.raises(ValueError, match="pattern"):
        ReplayOptions(include=["("]).validate()


def test_link_statistics_are_flattened_generically():
    from c4d_data.analysis.report import _flatten

    kv = SimpleNamespace
    array = kv(status=[kv(name="mavlink", values=[kv(key="rx_rate", value="12.5"), kv(key="lost", value="0")])])
    assert _flatten(array) == {"mavlink/rx_rate": "12.5", "mavlink/lost": "0"}
    assert _flatten(kv(rx=3, tx=4.5, label="x")) == {"rx": 3, "tx": 4.5, "label": "x"}
