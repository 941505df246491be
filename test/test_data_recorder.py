"""Recorder robustness with real processes on synthetic load (no flight graph): `kill -9` during a
recording leaves a file readable up to its last complete chunk and `repair` makes it valid; a
full disk (file-size limit, RLIMIT_FSIZE via prlimit: EFBIG, what a quota or a full small
filesystem gives) ends the file cleanly with one error line; bad files and bad arguments give
one clear line on stderr and a non-zero exit."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from c4d_testing import installed_executable, spin_for


def trigger(ros_node, name: str) -> str:
    """Call a recorder Trigger service; retried, since a just-killed recorder of the previous test
    may still be in the DDS graph and a request sent before the new one matched is lost."""
    from std_srvs.srv import Trigger

    node, executor = ros_node
    client = node.create_client(Trigger, name)
    try:
        assert client.wait_for_service(timeout_sec=30)
        for _ in range(6):
            future = client.call_async(Trigger.Request())
            if spin_for(executor, 5, future.done):
                reply = future.result()
                if reply.message.startswith("already recording "):
                    return reply.message.removeprefix("already recording ")
                assert reply.success, reply.message
                return reply.message
        raise AssertionError(f"{name}: no reply")
    finally:
        node.destroy_client(client)


def load(processes, **options) -> subprocess.Popen:
    args = [sys.executable, "-m", "c4d_data.synthetic"]
    for key, value in options.items():
        args += [f"--{key}"] if value is True else [f"--{key}", str(value)]
    return processes.spawn("load", args)


def contiguous(bag, topic: str) -> bool:
    from c4d_data.bag_reader import iter_messages

    seqs = [m.sequence for _, m in iter_messages(bag, [topic], log_time_order=False)]
    return bool(seqs) and seqs == list(range(seqs[0], seqs[0] + len(seqs)))


def test_kill9_keeps_complete_chunks_and_repair_makes_it_valid(processes, ros_node, ros_env, tmp_path):
    from rosbags.highlevel import AnyReader

    from c4d_data.bag_reader import open_bag

    out = tmp_path / "rec"
    recorder = processes.spawn("recorder", [installed_executable("c4d_data", "recorder"), "--ros-args", "-p",
                                            f"output_dir:={out}", "-p", "auto_arm:=false", "-p", "chunk_size:=65536",
                                            "-p", "max_chunk_age_s:=0.5"])
    publisher = load(processes, rate=2000, size=64, duration=30, delay=2)
    path = Path(trigger(ros_node, "recorder/start"))
    time.sleep(6.0)
    killed_at = time.time_ns()
    recorder.send_signal(signal.SIGKILL)
    recorder.wait(10)
    publisher.send_signal(signal.SIGINT)
    bag = open_bag(path)
    assert not bag.complete and "without a summary" in bag.problem
    assert bag.topics["/load/t0"].count > 4000 and contiguous(bag, "/load/t0")
    assert killed_at - bag.end_ns < 2.0e9, "more than the open chunk was lost"
    info = subprocess.run([installed_executable("c4d_data", "info"), str(path)], capture_output=True, text=True)
    assert info.returncode == 0 and "Complete:          NO" in info.stdout
    fixed = subprocess.run([installed_executable("c4d_data", "repair"), str(path)], capture_output=True, text=True)
    assert fixed.returncode == 0, fixed.stderr
    repaired = open_bag(path.with_name(path.stem + ".repaired.mcap"))
    assert repaired.complete and repaired.rosbag2["version"] == 9
    assert {n: t.count for n, t in repaired.topics.items()} == {n: t.count for n, t in bag.topics.items()}
    with AnyReader([repaired.path]) as reader:
        count = sum(1 for connection, _, raw in reader.messages() if reader.deserialize(raw, connection.msgtype))
    assert count == bag.message_count
    print(f"\nkill -9 after 6 s: {bag.message_count} messages kept, {(killed_at - bag.end_ns) * 1e-9:.2f} s lost")


def test_full_disk_ends_the_file_cleanly(processes, ros_node, tmp_path):
    from c4d_data.bag_reader import open_bag
    from c4d_data.repair import repair

    out, limit = tmp_path / "rec", 8 << 20
    recorder = processes.spawn("recorder", ["prlimit", f"--fsize={limit}", installed_executable("c4d_data", "recorder"),
                                            "--ros-args", "-p", f"output_dir:={out}", "-p", "auto_arm:=false",
                                            "-p", "compression:=none"])
    load(processes, rate=1000, size=10000, duration=30, delay=2, random=True)
    path = Path(trigger(ros_node, "recorder/start"))
    deadline = time.monotonic() + 20
    while "failed" not in processes.log_of(recorder) and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(1.0)
    assert recorder.poll() is None, "the recorder must survive a full disk"
    processes.stop()
    log = processes.log_of(recorder)
    errors = [line for line in log.splitlines() if line.startswith("recorder: error:")]
    assert len(errors) == 1 and "File too large" in errors[0] and "repair" in errors[0], log[-2000:]
    assert recorder.returncode == 1
    assert 0 < path.stat().st_size <= limit
    bag = open_bag(path)
    assert not bag.complete and bag.topics["/load/t0"].count > 100 and contiguous(bag, "/load/t0")
    _, written = repair(path, tmp_path / "repaired.mcap")
    assert open_bag(written.path).complete and written.message_count == bag.message_count


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    from mcap.reader import make_reader
    from mcap.writer import Writer

    from c4d_data.bag_writer import BagWriter
    from c4d_data.msgdef import full_text

    d = tmp_path_factory.mktemp("bad")
    good = BagWriter(d / "good.mcap")
    good.add_topic("/x", "std_msgs/msg/String", full_text("std_msgs/msg/String"), [])
    for k in range(20000):
        good.write("/x", b"\x00\x01\x00\x00\x06\x00\x00\x00hello\x00" + bytes(k % 7), k * 1_000_000, k * 1_000_000, k)
    good.close()
    data = (d / "good.mcap").read_bytes()
    (d / "garbage.mcap").write_bytes(b"this is not an mcap file at all")
    (d / "truncated.mcap").write_bytes(data[: len(data) // 2])
    with open(d / "good.mcap", "rb") as f:
        chunk = make_reader(f).get_summary().chunk_indexes[0]
    middle = bytearray(data)  # zero 64 bytes inside the first chunk's compressed data
    at = chunk.chunk_start_offset + chunk.chunk_length // 2
    middle[at: at + 64] = bytes(64)
    (d / "corrupt.mcap").write_bytes(bytes(middle))
    with open(d / "ros1.mcap", "wb") as f:
        w = Writer(f)
        w.start(profile="ros1", library="test")
        w.finish()
    unknown = BagWriter(d / "unknown.mcap")
    unknown.add_topic("/y", "no_such_pkg/msg/Thing", "int32 a\n", [])
    unknown.write("/y", b"\x00\x01\x00\x00\x07\x00\x00\x00", 1, 1)
    unknown.close()
    return d


@pytest.mark.parametrize(("tool", "name", "fragment"), [
    ("info", "garbage.mcap", "not an MCAP file"),
    ("info", "missing.mcap", "no such file"),
    ("info", "ros1.mcap", "profile is 'ros1', expected 'ros2'"),
    ("repair", "corrupt.mcap", "damaged"),
    ("analyze", "ros1.mcap", "expected 'ros2'"),
    ("repair", "garbage.mcap", "not an MCAP file"),
    ("replay", "unknown.mcap", "no topic to replay"),
])
def test_bad_files_give_one_clear_line(bad_files, ros_env, tool, name, fragment):
    result = subprocess.run([installed_executable("c4d_data", tool), str(bad_files / name)], capture_output=True,
                            text=True, env=ros_env, timeout=60)
    assert result.returncode != 0
    lines = [line for line in result.stderr.splitlines() if "error" in line]
    assert len(lines) == 1 and fragment in lines[0] and "Traceback" not in result.stderr, result.stderr


def test_truncated_file_stays_readable(bad_files, tmp_path):
    info = subprocess.run([installed_executable("c4d_data", "info"), str(bad_files / "truncated.mcap")],
                          capture_output=True, text=True)
    assert info.returncode == 0 and "Complete:          NO" in info.stdout
    report = subprocess.run([installed_executable("c4d_data", "analyze"), str(bad_files / "truncated.mcap"), "-o",
                             str(tmp_path / "r"), "--quiet"], capture_output=True, text=True)
    assert report.returncode == 0, report.stderr
    assert "INCOMPLETE" in (tmp_path / "r" / "index.html").read_text()


@pytest.mark.parametrize("argv", [["replay", "x.mcap", "--rate", "0"], ["analyze"], ["repair", "a", "-o", "b", "--in-place"],
                                  ["recorder", "--ros-args", "-p", "compression:=rar"]])
def test_bad_arguments(ros_env, argv):
    result = subprocess.run([installed_executable("c4d_data", argv[0]), *argv[1:]], capture_output=True, text=True,
                            env=ros_env, timeout=60)
    assert result.returncode == 2, result.stderr
    assert "error" in result.stderr.splitlines()[-1] and "Traceback" not in result.stderr


def test_out_of_range_parameter_exits_2_with_one_line_naming_it(ros_env, tmp_path):
    result = subprocess.run([installed_executable("c4d_data", "recorder"), "--ros-args", "-p", f"output_dir:={tmp_path}",
                             "-p", "queue_depth:=0"], capture_output=True, text=True, env=ros_env, timeout=60)
    assert result.returncode == 2, result.stderr
    assert result.stderr.splitlines() == ["recorder: error: parameter 'queue_depth': 0 is outside [1, 1e+06]"], result.stderr


def test_sigint_stops_cleanly_every_time(processes, ros_node, tmp_path):
    """Issue 14 item 15: the supervisor once needed SIGKILL after its SIGINT (1 stop in 17). Ten
    SIGINT stops with traffic — as the loop starts, as the file opens, mid-recording — each exit
    promptly with status 0 and leave complete, readable MCAP files."""
    from c4d_data.bag_reader import open_bag
    from c4d_interfaces.msg import VehicleStatus
    from c4d_ros import manifest

    node, _ = ros_node
    status = node.create_publisher(VehicleStatus, manifest.STATUS.name, manifest.STATUS.qos)
    status.publish(VehicleStatus(armed=True))  # latched: every recorder opens a file once it sees it
    load(processes, rate=2000, size=64, topics=4, duration=120, delay=0)
    exe, opened = installed_executable("c4d_data", "recorder"), 0
    # (stop after, delay): "loop" = the recorder's loop started; "file" = its flight file opened. Waiting
    # for the file's log line makes the mid-recording stops mid-recording however slow discovery is.
    stops = [("loop", 0.0), ("loop", 0.1), ("loop", 0.3), ("loop", 0.7), ("loop", 1.3),
             ("file", 0.0), ("file", 0.2), ("file", 0.5), ("file", 1.0), ("file", 2.0)]
    for k, (after, delay) in enumerate(stops):
        out = tmp_path / f"stop{k}"
        recorder = processes.spawn(f"recorder{k}", [exe, "--ros-args", "-p", f"output_dir:={out}",
                                                    "-p", "discovery_period_s:=0.2"])
        marker = "recording into" if after == "loop" else "recording started"
        deadline = time.monotonic() + 20.0
        while marker not in processes.log_of(recorder) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert marker in processes.log_of(recorder), f"stop {k}: no '{marker}' in 20 s\n{processes.log_of(recorder)}"
        time.sleep(delay)
        recorder.send_signal(signal.SIGINT)
        try:
            code = recorder.wait(8.0)  # the supervisor's grace is 10 s
        except subprocess.TimeoutExpired:
            raise AssertionError(f"stop {k} ({after} + {delay} s): still running 8 s after SIGINT\n"
                                 f"{processes.log_of(recorder)[-2000:]}") from None
        assert code == 0, f"stop {k} ({after} + {delay} s): exit {code}\n{processes.log_of(recorder)[-2000:]}"
        files = sorted(out.glob("*.mcap"))
        if after == "file":
            assert len(files) == 1, (k, files)  # the open file was closed, not lost
        opened += len(files)
        for path in files:
            bag = open_bag(path)
            assert bag.complete, (k, path, bag.problem)
    print(f"\n10 SIGINT stops: exit 0 each, {opened} files, all complete")
    node.destroy_publisher(status)
