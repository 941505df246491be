"""MAVLink 2 signing with pymavlink on both sides over real UDP: keys, acceptance, rejection counters."""

from __future__ import annotations

import hashlib
import socket
import struct
import time
from pathlib import Path

import pytest

from c4d_bridge_mavlink.signing import SigningConfig, SigningError, load_key, make_mavlink, mavlink, signing_timestamp
from c4d_bridge_mavlink.transport import MAX_PEERS, Router

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))
URL = "udpin:127.0.0.1:0"


def test_key_file_formats(tmp_path: Path) -> None:
    hex_file = tmp_path / "key.hex"
    hex_file.write_text(KEY.hex().upper() + "\n")
    raw_file = tmp_path / "key.bin"
    raw_file.write_bytes(KEY)
    assert load_key(hex_file) == KEY and load_key(raw_file) == KEY
    assert SigningConfig.from_file(hex_file).key == KEY


@pytest.mark.parametrize("content", [b"", b"00" * 31, b"zz" * 32, bytes(33), b"0" * 65])
def test_bad_key_files_are_one_line_errors(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "key"
    path.write_bytes(content)
    with pytest.raises(SigningError) as info:
        load_key(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_unreadable_key_file_and_bad_key() -> None:
    with pytest.raises(SigningError, match="cannot read"):
        load_key("/nonexistent/key")
    with pytest.raises(SigningError, match="32 bytes"):
        SigningConfig(b"short")


class SignedGcs:
    """A GCS talking to the router's udpin endpoint, signing with `key` (None: unsigned)."""

    def __init__(self, router: Router, key: bytes | None, sysid: int = 255, link_id: int = 3) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.dest = router.endpoints[URL].local_address
        config = SigningConfig(key) if key is not None else None
        self.mav = make_mavlink(sysid, 190, config, link_id)

    def frame(self, msg: mavlink.MAVLink_message) -> bytes:
        data = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        return data

    def send(self, msg: mavlink.MAVLink_message) -> bytes:
        data = self.frame(msg)
        self.sock.sendto(data, self.dest)
        return data

    def received(self, quiet: float) -> list[str]:
        """Types of the messages received until nothing came for `quiet` seconds."""
        self.sock.settimeout(quiet)
        types: list[str] = []
        try:
            while True:
                types += [m.get_type() for m in self.mav.parse_buffer(self.sock.recv(1024)) or []]
        except TimeoutError:
            return types

    def close(self) -> None:
        self.sock.close()


def heartbeat() -> mavlink.MAVLink_message:
    return mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3)


def arm() -> mavlink.MAVLink_message:
    return mavlink.MAVLink_command_long_message(1, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)


def radio_status() -> mavlink.MAVLink_message:
    return mavlink.MAVLink_radio_status_message(200, 190, 90, 80, 50, 0, 0)


def drain(router: Router, seconds: float = 0.3) -> list[str]:
    got = []
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        got += [r.message.get_type() for r in router.poll(0.05)]
    return got


def test_good_key_accepted_wrong_key_and_unsigned_rejected_and_counted() -> None:
    with Router([URL], signing=SigningConfig(KEY)) as router:
        good = SignedGcs(router, KEY)
        wrong, unsigned = SignedGcs(router, OTHER_KEY, sysid=254), SignedGcs(router, None, sysid=253)
        try:
            good.send(heartbeat())
            good.send(arm())
            wrong.send(heartbeat())
            wrong.send(arm())
            unsigned.send(arm())
            unsigned.send(radio_status())  # the spec's unsigned exemption
            assert sorted(drain(router)) == ["COMMAND_LONG", "HEARTBEAT", "RADIO_STATUS"]
            errors = router.stats()[URL].errors
            assert dict(errors) == {"bad_signature": 2, "unsigned": 1}
            # what reached the good GCS so far: the other GCSs' accepted broadcasts, forwarded unchanged
            assert good.received(0.2) == ["RADIO_STATUS"]
            # our replies are signed and verify with the shared key only
            assert router.send(mavlink.MAVLink_command_ack_message(400, 0, 0, 0, 255, 190)) == 1
            data = good.sock.recv(1024)
            assert data[2] & mavlink.MAVLINK_IFLAG_SIGNED
            (ack,) = good.mav.parse_buffer(data)
            assert ack.get_type() == "COMMAND_ACK" and good.mav.signing.goodsig_count == 1 and ack.get_srcSystem() == 1
            (rejected,) = make_mavlink(255, 190, SigningConfig(OTHER_KEY)).parse_buffer(data)
            assert rejected.get_type() == "BAD_DATA" and "signature" in rejected.reason
        finally:
            for gcs in (good, wrong, unsigned):
                gcs.close()


def test_replayed_frame_rejected() -> None:
    with Router([URL], signing=SigningConfig(KEY)) as router:
        gcs = SignedGcs(router, KEY)
        try:
            data = gcs.send(arm())
            gcs.sock.sendto(data, gcs.dest)  # same timestamp again
            assert drain(router) == ["COMMAND_LONG"]
            assert router.stats()[URL].errors["bad_signature"] == 1
        finally:
            gcs.close()


def _forged(genuine: bytes, timestamp: int) -> bytes:
    """The genuine frame with a future timestamp and a signature made with the wrong key."""
    body = bytearray(genuine[:-13])
    body += bytes([genuine[-13]]) + struct.pack("<Q", timestamp)[:6]
    return bytes(body + hashlib.sha256(OTHER_KEY + bytes(body)).digest()[:6])


def test_forged_future_timestamp_cannot_block_the_stream() -> None:
    gcs = make_mavlink(255, 190, SigningConfig(KEY), link_id=3)
    first = arm().pack(gcs)
    forged = _forged(first, signing_timestamp() + 10**9)
    later = arm().pack(gcs)
    ours = make_mavlink(1, 1, SigningConfig(KEY))
    assert [m.get_type() for m in ours.parse_buffer(first + forged + later)] == ["COMMAND_LONG", "BAD_DATA", "COMMAND_LONG"]
    # pymavlink's own check records the forged timestamp first and then rejects the genuine frame
    stock = mavlink.MAVLink(None, 1, 1)
    stock.robust_parsing = True
    stock.signing.secret_key, stock.signing.timestamp = KEY, signing_timestamp()
    stock.signing.allow_unsigned_callback = lambda _mav, _id: False
    assert [m.get_type() for m in stock.parse_buffer(first + forged + later)] == ["COMMAND_LONG", "BAD_DATA", "BAD_DATA"]


def test_only_signed_senders_take_a_peer_slot() -> None:
    """Issue 14 item 13: with signing on, neither 1-byte junk nor valid unsigned frames from 2 x MAX_PEERS
    addresses take a routing slot or evict the signed GCS; an unsigned RADIO_STATUS is processed but
    neither admits its sender nor redirects the GCS's route; everything is counted as junk."""
    with Router([URL], signing=SigningConfig(KEY)) as router:
        good = SignedGcs(router, KEY)
        junk = [SignedGcs(router, None, sysid=255) for _ in range(2 * MAX_PEERS)]
        try:
            good.send(heartbeat())
            assert drain(router) == ["HEARTBEAT"]
            for sender in junk:
                sender.sock.sendto(b"\x00", sender.dest)
                sender.send(heartbeat())
            junk[0].send(radio_status())  # same sysid/compid as the good GCS
            assert drain(router) == ["RADIO_STATUS"]
            endpoint = router.endpoints[URL]
            assert endpoint.peers() == [good.sock.getsockname()]
            assert endpoint.stats.junk == 4 * MAX_PEERS + 1 and endpoint.stats.errors["unsigned"] == 2 * MAX_PEERS
            assert router.routes[(255, 190)] == (URL, good.sock.getsockname())
            assert router.send(mavlink.MAVLink_command_ack_message(400, 0, 0, 0, 255, 190)) == 1
            assert good.received(0.3) == ["RADIO_STATUS", "COMMAND_ACK"]  # the forwarded broadcast, then our reply
        finally:
            for sender in (good, *junk):
                sender.close()


def test_signing_disabled_accepts_unsigned() -> None:
    with Router([URL]) as router:
        gcs = SignedGcs(router, None)
        try:
            gcs.send(arm())
            assert drain(router) == ["COMMAND_LONG"]
        finally:
            gcs.close()
