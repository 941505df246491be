"""MAVLink 2 message signing for the bridge's links: key loading, parsers that sign and verify.

What: a `SigningConfig` (32-byte secret key, whether outgoing frames are signed, which message
ids are accepted unsigned) and `make_mavlink()`, which builds the pymavlink `MAVLink` object of
one endpoint (our sysid/compid, signing state with that endpoint's link id and a timestamp from
the wall clock). Verification is pymavlink's (SHA-256 over key + frame, 48-bit signature,
per-(link id, sysid, compid) monotonic timestamps, new streams at most one minute behind).
Why here: the transport only has to count what pymavlink rejects; which frames are acceptable is
decided in one place.

Policy (https://mavlink.io/en/guide/message_signing.html, "Accepting Unsigned Packets"): when a
key is configured every incoming frame must carry a valid signature, except RADIO_STATUS, which
the spec says is always accepted unsigned (telemetry radios inject it and cannot sign). A
wrongly signed RADIO_STATUS is accepted too (pymavlink asks the same callback). Everything else
unsigned or wrongly signed is rejected; the transport counts it per endpoint ("unsigned" /
"bad_signature").

One fix over pymavlink 2.4.50: its `check_signature` records a stream's timestamp *before*
comparing the signature, so a single forged frame with a far-future timestamp would make every
later genuine frame of that (link, sysid, compid) stream look old and be rejected (a cheap
denial of service). `SigningMAVLink.check_signature` verifies the signature first.

Key file: 64 hexadecimal characters (surrounding whitespace ignored) or exactly 32 raw bytes;
anything else, or an unreadable file, is a `SigningError` with a one-line message.
"""

from __future__ import annotations

import hashlib
import os
import string
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink  # after MAVLINK20 is set

KEY_BYTES = 32
SIGNING_EPOCH_UNIX = 1420070400  # 2015-01-01 00:00:00 UTC, origin of MAVLink signing timestamps
TIMESTAMP_UNITS_PER_SECOND = 100_000  # 10 µs units
NEW_STREAM_WINDOW = 6_000_000  # a new stream may be one minute behind our timestamp
ALWAYS_ACCEPTED_UNSIGNED = frozenset({mavlink.MAVLINK_MSG_ID_RADIO_STATUS})


class SigningError(ValueError):
    """Unusable signing configuration (bad key file, bad key, bad link id); one-line message."""


@dataclass(frozen=True)
class SigningConfig:
    """Signing of one bridge: the shared secret, outgoing signing, the unsigned exemptions."""

    key: bytes
    sign_outgoing: bool = True
    accept_unsigned: frozenset[int] = field(default=ALWAYS_ACCEPTED_UNSIGNED)

    def __post_init__(self) -> None:
        if not isinstance(self.key, bytes) or len(self.key) != KEY_BYTES:
            size = len(self.key) if isinstance(self.key, bytes) else repr(self.key)
            raise SigningError(f"signing key must be {KEY_BYTES} bytes, got {size}")

    @classmethod
    def from_file(cls, path: str | os.PathLike[str], sign_outgoing: bool = True) -> SigningConfig:
        return cls(load_key(path), sign_outgoing=sign_outgoing)


def load_key(path: str | os.PathLike[str]) -> bytes:
    """The 32-byte secret from a key file (64 hex characters, or 32 raw bytes)."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise SigningError(f"signing key file {path}: cannot read it ({exc.strerror or exc})") from None
    text = data.strip()
    if len(text) == 2 * KEY_BYTES and all(chr(b) in string.hexdigits for b in text):
        return bytes.fromhex(text.decode("ascii"))
    if len(data) == KEY_BYTES:
        return data
    raise SigningError(
        f"signing key file {path}: expected {2 * KEY_BYTES} hex characters or {KEY_BYTES} raw bytes, got {len(data)} bytes"
    )


def signing_timestamp(unix_time: float | None = None) -> int:
    """MAVLink signing timestamp (10 µs units since 2015-01-01 UTC) of a Unix time (default: now)."""
    now = time.time() if unix_time is None else unix_time
    return max(0, int((now - SIGNING_EPOCH_UNIX) * TIMESTAMP_UNITS_PER_SECOND))


class SigningMAVLink(mavlink.MAVLink):
    """pymavlink's MAVLink with a signature check that cannot be poisoned by forged timestamps."""

    def check_signature(self, msgbuf: bytearray, srcSystem: int, srcComponent: int) -> bool:
        signing = self.signing
        assert signing.secret_key is not None
        link_id = msgbuf[-13]
        low, high = struct.unpack("<IH", bytes(msgbuf[-12:-6]))
        timestamp = low + (high << 32)
        digest = hashlib.sha256(signing.secret_key + bytes(msgbuf[:-6])).digest()[:6]
        if digest != bytes(msgbuf[-6:]):
            return False
        stream = (link_id, srcSystem, srcComponent)
        previous = signing.stream_timestamps.get(stream)
        if previous is not None and timestamp <= previous:
            return False  # replayed or reordered
        if previous is None and timestamp + NEW_STREAM_WINDOW < signing.timestamp:
            return False  # a new stream more than a minute in the past
        signing.stream_timestamps[stream] = timestamp
        signing.timestamp = max(signing.timestamp, timestamp)
        return True


def make_mavlink(src_system: int, src_component: int, config: SigningConfig | None = None, link_id: int = 0) -> mavlink.MAVLink:
    """The MAVLink 2 parser/packer of one endpoint: our identity, robust parsing (bad input becomes
    BAD_DATA messages, never an exception) and, with a config, signing on link `link_id`."""
    if not 0 <= link_id <= 255:
        raise SigningError(f"signing link id must be 0..255, got {link_id}")
    mav = SigningMAVLink(None, srcSystem=src_system, srcComponent=src_component)
    mav.robust_parsing = True
    if config is not None:
        allowed = config.accept_unsigned
        mav.signing.secret_key = config.key
        mav.signing.link_id = link_id
        mav.signing.timestamp = signing_timestamp()
        mav.signing.sign_outgoing = config.sign_outgoing
        mav.signing.allow_unsigned_callback = lambda _mav, msg_id: msg_id in allowed
    return mav
