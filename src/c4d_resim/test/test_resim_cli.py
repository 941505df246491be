"""resim's bad input: one line `resim: error: ...` on stderr, non-zero exit — files that are not MCAP,
MCAPs without c4d journals (the missing topics named), truncated files (pointing to `repair`),
malformed overrides. (Overrides that do not exist or are out of range need a real flight's
snapshot: test/test_data_flight.py checks them on its recorded flight.)"""

from __future__ import annotations

import pytest

from c4d_data.bag_writer import BagWriter
from c4d_resim import cli


def _run(capsys, *argv: str) -> tuple[int, list[str]]:
    code = cli.main(list(argv))
    return code, [line for line in capsys.readouterr().err.splitlines() if line.strip()]


def test_not_an_mcap(tmp_path, capsys):
    path = tmp_path / "notes.mcap"
    path.write_text("hello, not a recording\n")
    code, err = _run(capsys, str(path))
    assert code == 1 and len(err) == 1 and err[0].startswith("resim: error: ")


def test_an_mcap_of_another_tool_names_the_missing_topics(tmp_path, capsys):
    path = tmp_path / "other.mcap"
    w = BagWriter(path)
    w.add_topic("/chatter", "std_msgs/msg/String", "string data", "")
    w.write("/chatter", b"\x00\x01\x00\x00\x03\x00\x00\x00hi\x00", 1, 1)
    w.close()
    code, err = _run(capsys, str(path))
    assert code == 1 and len(err) == 1
    assert "missing topic(s) /navigation/journal, /gnc/journal, /perception/imu, /navigation/state, " \
           "/control/actuators" in err[0]


def test_a_truncated_file_points_to_repair(tmp_path, capsys):
    path = tmp_path / "cut.mcap"
    w = BagWriter(path, chunk_size=1024)
    w.add_topic("/chatter", "std_msgs/msg/String", "string data", "")
    for i in range(200):
        w.write("/chatter", b"\x00\x01\x00\x00\x03\x00\x00\x00hi\x00", i, i)
    w.close()
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    code, err = _run(capsys, str(path))
    assert code == 1 and len(err) == 1 and "repair" in err[0]


@pytest.mark.parametrize("override", ["gps_gate:=3", "navigation.gps_gate=3", "mission.speed:=2"])
def test_malformed_overrides_exit_2(tmp_path, capsys, override):
    code, err = _run(capsys, str(tmp_path / "any.mcap"), "-p", override)
    assert code == 2 and len(err) == 1 and "expected navigation.<param>:=<value>" in err[0]
