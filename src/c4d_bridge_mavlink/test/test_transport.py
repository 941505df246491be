"""Link layer over real sockets and a real pty: URLs, UDP in/out, serial, routing, bad input, link loss."""

from __future__ import annotations

import os
import socket
import time

import pytest

from c4d_bridge_mavlink.link_monitor import LinkMonitor
from c4d_bridge_mavlink.signing import make_mavlink, mavlink
from c4d_bridge_mavlink.transport import MAX_PEERS, Router, could_hold_frame, parse_endpoint_url


class Gcs:
    """A ground station: a UDP socket and its own pymavlink packer/parser."""

    def __init__(self, sysid: int = 255, dest: tuple[str, int] | None = None, bind_port: int = 0) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", bind_port))
        self.sock.settimeout(1.0)
        self.mav = make_mavlink(sysid, mavlink.MAV_COMP_ID_MISSIONPLANNER)
        self.dest = dest

    @property
    def port(self) -> int:
        return self.sock.getsockname()[1]

    def frame(self, msg: mavlink.MAVLink_message) -> bytes:
        data = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        return data

    def send(self, msg: mavlink.MAVLink_message) -> None:
        self.sock.sendto(self.frame(msg), self.dest)

    def recv(self, timeout: float = 1.0) -> list[mavlink.MAVLink_message]:
        self.sock.settimeout(timeout)
        try:
            data = self.sock.recv(65535)
        except TimeoutError:
            return []
        return self.mav.parse_buffer(data) or []

    def close(self) -> None:
        self.sock.close()


def heartbeat(kind: int = mavlink.MAV_TYPE_GCS) -> mavlink.MAVLink_message:
    return mavlink.MAVLink_heartbeat_message(kind, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3)


def command(target_system: int, target_component: int = 0) -> mavlink.MAVLink_message:
    return mavlink.MAVLink_command_long_message(target_system, target_component, 400, 0, 1, 0, 0, 0, 0, 0, 0)


def poll_until(router: Router, count: int, timeout: float = 2.0) -> list:
    got: list = []
    deadline = time.monotonic() + timeout
    while len(got) < count and time.monotonic() < deadline:
        got += router.poll(0.05)
    return got


def udpin_port(router: Router, name: str) -> int:
    return router.endpoints[name].local_address[1]


@pytest.mark.parametrize(
    "url, kind, address, number",
    [
        ("udpin:127.0.0.1:14550", "udpin", "127.0.0.1", 14550),
        ("udpin:14550", "udpin", "127.0.0.1", 14550),
        ("udpout:127.0.0.1:14540", "udpout", "127.0.0.1", 14540),
        ("serial:/dev/ttyUSB0:57600", "serial", "/dev/ttyUSB0", 57600),
    ],
)
def test_good_urls(url: str, kind: str, address: str, number: int) -> None:
    parsed = parse_endpoint_url(url)
    assert (parsed.kind, parsed.address, parsed.number) == (kind, address, number)


@pytest.mark.parametrize(
    "url", ["", "udp:1.2.3.4:5", "udpin:host:port", "udpout:127.0.0.1", "udpout:127.0.0.1:70000", "serial:/dev/x", "serial::9600",
            "serial:/dev/x:0", "tcp:1:2", "udpout::5"],
)
def test_bad_urls_are_one_line_value_errors(url: str) -> None:
    with pytest.raises(ValueError) as info:
        parse_endpoint_url(url)
    assert "\n" not in str(info.value) and url in str(info.value)


def test_unopenable_endpoints_and_bad_sysid() -> None:
    with pytest.raises(ValueError, match="cannot open"):
        Router(["serial:/nonexistent/tty:57600"])
    with pytest.raises(ValueError, match="sysid"):
        Router(["udpin:127.0.0.1:0"], sysid=0)


def test_udpin_learns_gcs_and_replies_with_our_identity() -> None:
    with Router(["udpin:127.0.0.1:0"], sysid=7) as router:
        gcs = Gcs(dest=("127.0.0.1", udpin_port(router, "udpin:127.0.0.1:0")))
        try:
            assert router.send(heartbeat(mavlink.MAV_TYPE_QUADROTOR)) == 0  # no peer known yet
            gcs.send(heartbeat())
            got = poll_until(router, 1)
            assert [r.message.get_type() for r in got] == ["HEARTBEAT"]
            assert got[0].peer == ("127.0.0.1", gcs.port)
            assert router.send(heartbeat(mavlink.MAV_TYPE_QUADROTOR)) == 1
            (reply,) = gcs.recv()
            assert (reply.get_srcSystem(), reply.get_srcComponent(), reply.type) == (7, 1, mavlink.MAV_TYPE_QUADROTOR)
            stats = router.stats()["udpin:127.0.0.1:0"]
            assert (stats.rx_frames, stats.tx_frames, stats.rx_errors) == (1, 1, 0)
        finally:
            gcs.close()


def test_udpout_sends_to_fixed_gcs_and_hears_it() -> None:
    gcs = Gcs()
    url = f"udpout:127.0.0.1:{gcs.port}"
    try:
        with Router([url]) as router:
            assert router.send(heartbeat(mavlink.MAV_TYPE_QUADROTOR)) == 1
            (msg,) = gcs.recv()
            assert msg.get_srcSystem() == 1
            source = router.endpoints[url].sock.getsockname()
            gcs.sock.sendto(gcs.frame(heartbeat()), source)
            assert [r.message.get_srcSystem() for r in poll_until(router, 1)] == [255]
    finally:
        gcs.close()


def test_serial_endpoint_over_a_pty_reassembles_split_frames() -> None:
    master, slave = os.openpty()
    url = f"serial:{os.ttyname(slave)}:57600"
    try:
        with Router([url]) as router:
            gcs = make_mavlink(255, 190)
            frame = heartbeat().pack(gcs)
            os.write(master, frame[:5])
            assert router.poll(0.1) == []
            os.write(master, frame[5:] + b"\x00\x01junk" + command(1).pack(gcs))
            got = poll_until(router, 2)
            assert [r.message.get_type() for r in got] == ["HEARTBEAT", "COMMAND_LONG"]
            assert router.stats()[url].errors["prefix"] == 1
            assert router.send(heartbeat(mavlink.MAV_TYPE_QUADROTOR)) == 1
            time.sleep(0.05)
            out = gcs.parse_buffer(os.read(master, 4096))
            assert [m.get_type() for m in out] == ["HEARTBEAT"] and out[0].get_srcSystem() == 1
    finally:
        os.close(master)
        os.close(slave)


def test_routing_between_two_gcs_endpoints() -> None:
    a, b = "udpin:127.0.0.1:0", "udpin:127.0.0.2:0"
    with Router([a, b]) as router:
        gcs1 = Gcs(255, ("127.0.0.1", udpin_port(router, a)))
        gcs2 = Gcs(254, ("127.0.0.2", udpin_port(router, b)))
        try:
            gcs2.send(heartbeat())  # B learns gcs2; nobody else to forward to yet
            assert len(poll_until(router, 1)) == 1
            gcs1.send(heartbeat())  # broadcast: local, and forwarded unchanged to gcs2
            assert len(poll_until(router, 1)) == 1
            (fwd,) = gcs2.recv()
            assert (fwd.get_type(), fwd.get_srcSystem(), fwd.get_srcComponent()) == ("HEARTBEAT", 255, 190)
            assert gcs1.recv(0.2) == []  # never back to its source
            gcs2.send(command(255))  # addressed to gcs1: forwarded only, not for us
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline:
                assert router.poll(0.05) == []
            (cmd,) = gcs1.recv()
            assert (cmd.get_type(), cmd.get_srcSystem(), cmd.target_system) == ("COMMAND_LONG", 254, 255)
            gcs2.send(command(1, 1))  # addressed to us: local only
            assert [r.message.target_system for r in poll_until(router, 1)] == [1]
            assert gcs1.recv(0.2) == []
            gcs2.send(command(99))  # unknown system: dropped, not local
            time.sleep(0.1)
            assert router.poll(0.1) == [] and gcs1.recv(0.1) == []
            # our own addressed message goes only where the target was seen
            assert router.send(mavlink.MAVLink_command_ack_message(400, 0, 0, 0, 254, 190)) == 1
            assert [m.get_type() for m in gcs2.recv()] == ["COMMAND_ACK"] and gcs1.recv(0.2) == []
            assert router.send(mavlink.MAVLink_command_ack_message(400, 0, 0, 0, 77, 0)) == 0
            assert router.stats()[b].forwarded == 1 and router.stats()[a].forwarded == 1
        finally:
            gcs1.close()
            gcs2.close()


def test_two_gcs_on_one_udpin_endpoint_see_each_other() -> None:
    url = "udpin:127.0.0.1:0"
    with Router([url]) as router:
        dest = ("127.0.0.1", udpin_port(router, url))
        gcs1, gcs2 = Gcs(255, dest), Gcs(254, dest)
        try:
            gcs1.send(heartbeat())
            poll_until(router, 1)
            gcs2.send(heartbeat())
            poll_until(router, 1)
            assert [m.get_srcSystem() for m in gcs1.recv()] == [254]
            assert gcs2.recv(0.2) == []
        finally:
            gcs1.close()
            gcs2.close()


def _recrc(frame: bytearray, crc_extra: int) -> bytes:
    crc = mavlink.x25crc(frame[1:-2])
    crc.accumulate(bytes([crc_extra]))
    frame[-2:] = crc.crc.to_bytes(2, "little")
    return bytes(frame)


def test_bad_input_is_counted_never_raised() -> None:
    url = "udpin:127.0.0.1:0"
    with Router([url]) as router:
        gcs = Gcs(dest=("127.0.0.1", udpin_port(router, url)))
        try:
            good = gcs.frame(heartbeat())
            bad_crc = bytearray(good)
            bad_crc[-1] ^= 0xFF
            unknown = bytearray(gcs.frame(heartbeat()))
            unknown[7:10] = (60000).to_bytes(3, "little")
            bad_flags = bytearray(gcs.frame(heartbeat()))
            bad_flags[2] = 0x80
            bad_flags = _recrc(bad_flags, mavlink.MAVLink_heartbeat_message.crc_extra)
            gcs.sock.sendto(good, gcs.dest)  # admitted first: then its bad input is parsed and counted by reason
            assert len(poll_until(router, 1)) == 1
            for data in (bytes(bad_crc), bytes(unknown), bad_flags, b"\x01\x02garbage", good[:7], good[:-3], b"", good):
                gcs.sock.sendto(data, gcs.dest)
            got = poll_until(router, 1)
            time.sleep(0.1)
            got += router.poll(0.1)
            assert [r.message.get_type() for r in got] == ["HEARTBEAT"]
            stats = router.stats()[url]
            assert dict(stats.errors) == {"crc": 1, "unknown_id": 1, "incompat_flags": 1, "prefix": 1, "truncated": 2}
            assert stats.junk == 0
        finally:
            gcs.close()


def test_junk_senders_take_no_peer_slot_without_signing() -> None:
    """Issue 14 item 13: 1-byte datagrams from many addresses used to fill the 16-slot peer table and
    evict the GCS. Now a source needs one valid frame to take a slot; junk is dropped and counted."""
    url = "udpin:127.0.0.1:0"
    with Router([url]) as router:
        dest = ("127.0.0.1", udpin_port(router, url))
        gcs = Gcs(dest=dest)
        junk = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2 * MAX_PEERS)]
        try:
            gcs.send(heartbeat())
            assert len(poll_until(router, 1)) == 1
            for sock in junk:
                sock.sendto(b"\x00", dest)
                sock.sendto(b"\xfd" + bytes(20), dest)  # a start byte, then nothing valid: parsed, still junk
            deadline = time.monotonic() + 2.0
            endpoint = router.endpoints[url]
            while endpoint.stats.junk < 4 * MAX_PEERS and time.monotonic() < deadline:
                router.poll(0.05)
            assert endpoint.stats.junk == 4 * MAX_PEERS
            assert endpoint.peers() == [("127.0.0.1", gcs.port)]
            assert router.send(heartbeat(mavlink.MAV_TYPE_QUADROTOR)) == 1
            assert [m.get_type() for m in gcs.recv()] == ["HEARTBEAT"]
            # a source with a valid frame is a peer (unsigned links: today's behaviour)
            junk[0].sendto(Gcs(sysid=7).frame(heartbeat()), dest)
            poll_until(router, 1)
            assert len(endpoint.peers()) == 2
        finally:
            gcs.close()
            for sock in junk:
                sock.close()


def test_could_hold_frame() -> None:
    frame = Gcs().frame(heartbeat())
    assert could_hold_frame(frame) and could_hold_frame(frame[:8])
    assert not could_hold_frame(b"\xfd") and not could_hold_frame(b"") and not could_hold_frame(b"\x00" + frame[1:])


def test_link_monitor_from_real_heartbeats() -> None:
    url = "udpin:127.0.0.1:0"
    monitor = LinkMonitor(timeout_s=2.0)
    assert monitor.status(0.0).up is False
    with Router([url]) as router:
        gcs = Gcs(dest=("127.0.0.1", udpin_port(router, url)))
        try:
            gcs.send(heartbeat(mavlink.MAV_TYPE_QUADROTOR))  # not a GCS: does not count
            gcs.send(heartbeat())
            for received in poll_until(router, 2):
                monitor.observe(received, 10.0)
        finally:
            gcs.close()
    assert monitor.status(11.0).up and monitor.status(11.0).gcs == ((255, url, 1.0),)
    lost = monitor.status(12.5)
    assert not lost.up and lost.losses == 1 and lost.since_heartbeat_s == pytest.approx(2.5)
    assert monitor.status(13.0).losses == 1
