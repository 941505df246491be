"""MAVLink 2 link layer of the bridge: endpoints (UDP listen, UDP connect-out, serial) and a router.

What:
- `parse_endpoint_url(url)`: `udpin:HOST:PORT` (listen, default host 127.0.0.1 with `udpin:PORT`;
  port 0 = ephemeral), `udpout:HOST:PORT` (send to a fixed GCS address), `serial:DEVICE:BAUD`
  (pyserial; a pty works). Anything else is a `ValueError` with a one-line message.
- `Endpoint`: one open link with its own pymavlink parser/packer (our sysid, compid 1,
  optional signing with the endpoint's link id), raw byte I/O, and `EndpointStats` (bytes and
  frames both ways, receive errors counted by reason: crc, unsigned, bad_signature, unknown_id,
  prefix, length, incompat_flags, truncated, malformed, io). A udpin endpoint learns its GCS peers
  from incoming datagrams and sends to all of them; each datagram is parsed on its own (a truncated
  frame never swallows the next datagram).
- Peer admission (udpin): a source address takes one of the MAX_PEERS routing slots (least
  recently admitted-and-heard evicted) only with a datagram holding at least one accepted frame
  that is *authenticated*: any accepted frame without signing, a frame with a valid signature when
  signing is on (an unsigned RADIO_STATUS is accepted for processing but admits nobody). Datagrams
  from unknown sources that admit nothing are dropped and counted (`EndpointStats.junk`); one that
  cannot even hold a frame (too short, no MAVLink start byte) is dropped before parsing. Why: a
  flood of junk from many addresses used to fill the table and evict the real GCS, whose
  telemetry then stopped (issue 14 item 13).
- `Router`: several endpoints behind one `selectors` loop. `poll(timeout)` reads every ready
  endpoint, parses, learns routes, forwards, and returns the messages to process locally;
  `send(msg)` sends our own message by the routing rules.
Why: the ROS node (bridge_node.py) only sees decoded, accepted messages and never touches a
socket; everything a GCS can send is untrusted, so parsing never raises — bad input is counted.

Routing (https://mavlink.io/en/guide/routing.html). A *link* is an endpoint, or one peer of a
udpin endpoint. Every accepted frame teaches "(sysid, compid) is reachable on this link".
- Local: broadcast (no/zero target_system), or target_system == ours (a target_component of 0, ours,
  or one never seen elsewhere). Locally processed messages are returned by `poll`.
- Forwarded, unchanged (raw bytes, original ids, seq and signature), never back to the source
  link: broadcasts to every other link; addressed frames only to links where the target was seen
  (target system ≠ ours), or where the target component of our system was seen. This is what lets
  two GCSs on different endpoints see each other. Frames with unknown message ids are counted and
  not forwarded: pymavlink cannot check their CRC (no CRC_EXTRA) nor their signature.
- Our own messages (`send`): broadcast to every link; addressed ones only where the target was seen
  (none if unknown — the spec forbids sending to unknown destinations); the number of links used
  is returned.
Signing (signing.py): when configured, each endpoint signs outgoing frames and rejects unsigned /
wrongly signed input except RADIO_STATUS; rejections are counted per endpoint.
"""

from __future__ import annotations

import os
import selectors
import socket
import time
from collections import Counter, OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import serial

from .signing import SigningConfig, make_mavlink, mavlink

OWN_COMPONENT = mavlink.MAV_COMP_ID_AUTOPILOT1
DEFAULT_UDP_HOST = "127.0.0.1"
MAX_PEERS = 16
MAX_DATAGRAM = 65535
MAX_READS_PER_POLL = 64  # datagrams / serial reads per endpoint per poll (fairness between links)
SERIAL_TX_BUFFER = 65536  # bytes kept when a serial port cannot take a frame right away

Peer = tuple[str, int]
LinkKey = tuple[str, Peer | None]  # (endpoint name, udpin peer or None)

_BAD_DATA_REASONS = (  # pymavlink MAVLink_bad_data reason prefix -> counter name
    ("Bad prefix", "prefix"),
    ("invalid MAVLink CRC", "crc"),
    ("invalid MAVLink message length", "length"),
    ("invalid incompat_flags", "incompat_flags"),
)


@dataclass(frozen=True)
class EndpointUrl:
    """A parsed endpoint URL; `address` is the IP/host (udp) or device path (serial), `number` the
    UDP port or the serial baud rate."""

    kind: str
    address: str
    number: int
    text: str


def parse_endpoint_url(url: str) -> EndpointUrl:
    """Parse `udpin:[HOST:]PORT`, `udpout:HOST:PORT` or `serial:DEVICE:BAUD` (ValueError if bad)."""
    if not isinstance(url, str) or ":" not in url:
        raise ValueError(f"bad endpoint {url!r}: expected udpin:[HOST:]PORT, udpout:HOST:PORT or serial:DEVICE:BAUD")
    kind, rest = url.split(":", 1)
    if kind not in ("udpin", "udpout", "serial"):
        raise ValueError(f"bad endpoint {url!r}: unknown kind '{kind}' (udpin, udpout, serial)")
    if kind == "udpin" and ":" not in rest:
        rest = f"{DEFAULT_UDP_HOST}:{rest}"
    address, sep, number_text = rest.rpartition(":")
    what = "baud rate" if kind == "serial" else "port"
    if not sep or not address:
        raise ValueError(f"bad endpoint {url!r}: missing {'device' if kind == 'serial' else 'host'}")
    try:
        number = int(number_text)
    except ValueError:
        raise ValueError(f"bad endpoint {url!r}: {what} '{number_text}' is not an integer") from None
    low = 1 if kind != "udpin" else 0
    high = 65535 if kind != "serial" else 20_000_000
    if not low <= number <= high:
        raise ValueError(f"bad endpoint {url!r}: {what} {number} out of range {low}..{high}")
    return EndpointUrl(kind, address, number, url)


@dataclass
class EndpointStats:
    """Counters of one endpoint; `errors` counts rejected input by reason."""

    rx_bytes: int = 0
    rx_frames: int = 0  # accepted frames
    tx_bytes: int = 0
    tx_frames: int = 0
    tx_dropped: int = 0  # frames not sent (no peer yet, socket error, serial buffer full)
    forwarded: int = 0  # frames from other links written here
    junk: int = 0  # datagrams from unknown sources that admitted nothing (dropped; udpin only)
    errors: Counter = field(default_factory=Counter)
    last_rx: float | None = None  # time.monotonic() of the last accepted frame

    @property
    def rx_errors(self) -> int:
        return sum(self.errors.values())


class Endpoint:
    """One open link. Subclasses implement `_read_chunks()` and `_write(data, peer)`."""

    kind = ""

    def __init__(self, url: EndpointUrl, sysid: int, compid: int, signing: SigningConfig | None, link_id: int) -> None:
        self.url = url
        self.name = url.text
        self.mav = make_mavlink(sysid, compid, signing, link_id)
        self.stats = EndpointStats()
        self.closed = False
        self.last_error = ""

    # -- raw I/O ------------------------------------------------------------------------------
    def fileno(self) -> int:
        raise NotImplementedError

    def _read_chunks(self) -> list[tuple[bytes, Peer | None]]:
        raise NotImplementedError

    def _write(self, data: bytes, peer: Peer | None) -> bool:
        raise NotImplementedError

    def peers(self) -> list[Peer | None]:
        """Destinations of a broadcast on this endpoint (udpin: learned peers; others: [None])."""
        return [None]

    def close(self) -> None:
        self.closed = True

    # -- frames -------------------------------------------------------------------------------
    def pack(self, msg: mavlink.MAVLink_message) -> bytes:
        """Encode one of our messages with this endpoint's seq and signing (advances seq)."""
        data = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        return data

    def write(self, data: bytes, peer: Peer | None = None, exclude: Peer | None = None) -> int:
        """Send one frame to `peer` (None: every peer but `exclude`); returns destinations reached."""
        if self.closed:
            self.stats.tx_dropped += 1
            return 0
        targets = [peer] if peer is not None else [p for p in self.peers() if p is None or p != exclude]
        sent = 0
        for target in targets:
            try:
                ok = self._write(data, target)
            except OSError as exc:
                ok = False
                self.last_error = f"write: {exc}"
            if ok:
                sent += 1
                self.stats.tx_bytes += len(data)
                self.stats.tx_frames += 1
            else:
                self.stats.tx_dropped += 1
        if not targets:
            self.stats.tx_dropped += 1
        return sent

    def read(self) -> list[tuple[mavlink.MAVLink_message, Peer | None]]:
        """Read what is available and return the accepted frames with their source peer."""
        try:
            chunks = self._read_chunks()
        except (OSError, serial.SerialException) as exc:
            self.stats.errors["io"] += 1
            self.last_error = f"read: {exc}"
            self.closed = True
            return []
        out: list[tuple[mavlink.MAVLink_message, Peer | None]] = []
        for data, peer in chunks:
            self.stats.rx_bytes += len(data)
            if not self.is_peer(peer) and not could_hold_frame(data):
                self.stats.junk += 1  # cheap: not even parsed
                continue
            messages = self._parse(data, isolated=peer is not None or self.kind != "serial")
            if not self._admit(peer, messages):
                self.stats.junk += 1
            out.extend((msg, peer) for msg in messages)
        if out:
            self.stats.last_rx = time.monotonic()
        return out

    def is_peer(self, peer: Peer | None) -> bool:
        """Whether `peer` holds a routing slot (always, for the single-destination endpoints)."""
        return True

    def _admit(self, peer: Peer | None, messages: list[mavlink.MAVLink_message]) -> bool:
        """Give `peer` a slot if `messages` (one datagram's accepted frames) authenticate it; True if it holds one."""
        return True

    def authenticated(self, msg: mavlink.MAVLink_message) -> bool:
        """An accepted frame that may admit its sender: signed and verified when signing is on, else any."""
        return self.mav.signing.secret_key is None or bool(msg.get_signed())

    def _parse(self, data: bytes, isolated: bool) -> list[mavlink.MAVLink_message]:
        mav = self.mav
        try:
            messages = mav.parse_buffer(data) or []
        except Exception:  # untrusted input must never take the bridge down
            self.stats.errors["malformed"] += 1
            messages = []
            _reset_parser(mav)
        if isolated and mav.buf_len() > 0:  # a datagram ended inside a frame
            self.stats.errors["truncated"] += 1
            _reset_parser(mav)
        accepted = []
        for msg in messages:
            reason = self._classify(msg)
            if reason:
                self.stats.errors[reason] += 1
            else:
                self.stats.rx_frames += 1
                accepted.append(msg)
        return accepted

    @staticmethod
    def _classify(msg: mavlink.MAVLink_message) -> str:
        """'' for an accepted message, else the error counter it belongs to."""
        if isinstance(msg, mavlink.MAVLink_unknown):
            return "unknown_id"
        if not isinstance(msg, mavlink.MAVLink_bad_data):
            return ""
        reason = str(msg.reason)
        if reason.startswith("Invalid signature"):
            raw = bytes(msg.data)
            signed = len(raw) > 2 and raw[0] == mavlink.PROTOCOL_MARKER_V2 and raw[2] & mavlink.MAVLINK_IFLAG_SIGNED
            return "bad_signature" if signed else "unsigned"
        for prefix, name in _BAD_DATA_REASONS:
            if reason.startswith(prefix):
                return name
        return "malformed"


MIN_FRAME_BYTES = 8  # the shortest MAVLink frame (v1, empty payload); v2 needs 12


def could_hold_frame(data: bytes) -> bool:
    """Whether a datagram can hold a MAVLink frame at all: long enough and starting with a v1 / v2
    start byte (a sender that frames correctly starts every datagram with one)."""
    return len(data) >= MIN_FRAME_BYTES and data[0] in (mavlink.PROTOCOL_MARKER_V1, mavlink.PROTOCOL_MARKER_V2)


def _reset_parser(mav: mavlink.MAVLink) -> None:
    mav.buf = bytearray()
    mav.buf_index = 0
    mav.expected_length = mavlink.HEADER_LEN_V1 + 2


class UdpInEndpoint(Endpoint):
    """Listening UDP socket; peers learned from incoming datagrams."""

    kind = "udpin"

    def __init__(self, url: EndpointUrl, *args: object) -> None:
        super().__init__(url, *args)  # type: ignore[arg-type]
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.setblocking(False)
            self.sock.bind((url.address, url.number))
        except OSError as exc:
            self.sock.close()
            raise ValueError(f"endpoint {url.text}: cannot listen ({exc.strerror or exc})") from None
        self._peers: OrderedDict[Peer, float] = OrderedDict()

    @property
    def local_address(self) -> Peer:
        return self.sock.getsockname()

    def fileno(self) -> int:
        return self.sock.fileno()

    def peers(self) -> list[Peer | None]:
        return list(self._peers)

    def _read_chunks(self) -> list[tuple[bytes, Peer | None]]:
        chunks: list[tuple[bytes, Peer | None]] = []
        for _ in range(MAX_READS_PER_POLL):
            try:
                data, peer = self.sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                break
            except ConnectionError:
                continue  # ICMP error of an earlier send: not fatal for a listening socket
            chunks.append((data, peer))
        return chunks

    def is_peer(self, peer: Peer | None) -> bool:
        return peer in self._peers

    def _admit(self, peer: Peer | None, messages: list[mavlink.MAVLink_message]) -> bool:
        if peer is None:
            return False
        if any(self.authenticated(msg) for msg in messages):
            self._peers[peer] = time.monotonic()
            self._peers.move_to_end(peer)
            while len(self._peers) > MAX_PEERS:
                self._peers.popitem(last=False)
            return True
        return peer in self._peers

    def _write(self, data: bytes, peer: Peer | None) -> bool:
        if peer is None:
            return False
        try:
            return self.sock.sendto(data, peer) == len(data)
        except (BlockingIOError, ConnectionError):
            return False

    def close(self) -> None:
        super().close()
        self.sock.close()


class UdpOutEndpoint(Endpoint):
    """UDP socket connected to a fixed GCS address (only that address is heard)."""

    kind = "udpout"

    def __init__(self, url: EndpointUrl, *args: object) -> None:
        super().__init__(url, *args)  # type: ignore[arg-type]
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.setblocking(False)
            self.sock.connect((url.address, url.number))
        except OSError as exc:
            self.sock.close()
            raise ValueError(f"endpoint {url.text}: cannot connect ({exc.strerror or exc})") from None

    def fileno(self) -> int:
        return self.sock.fileno()

    def _read_chunks(self) -> list[tuple[bytes, Peer | None]]:
        chunks: list[tuple[bytes, Peer | None]] = []
        for _ in range(MAX_READS_PER_POLL):
            try:
                chunks.append((self.sock.recv(MAX_DATAGRAM), None))
            except (BlockingIOError, InterruptedError):
                break
            except ConnectionError:
                continue  # GCS not listening yet (ICMP port unreachable)
        return chunks

    def _write(self, data: bytes, peer: Peer | None) -> bool:
        try:
            return self.sock.send(data) == len(data)
        except (BlockingIOError, ConnectionError):
            return False

    def close(self) -> None:
        super().close()
        self.sock.close()


class SerialEndpoint(Endpoint):
    """Serial port (pyserial, non-blocking); frames the port cannot take yet wait in a bounded buffer."""

    kind = "serial"

    def __init__(self, url: EndpointUrl, *args: object) -> None:
        super().__init__(url, *args)  # type: ignore[arg-type]
        try:
            self.port = serial.Serial(url.address, baudrate=url.number, timeout=0, write_timeout=0, exclusive=True)
        except (OSError, serial.SerialException, ValueError) as exc:
            raise ValueError(f"endpoint {url.text}: cannot open ({_one_line(exc)})") from None
        self._pending = bytearray()

    def fileno(self) -> int:
        return self.port.fileno()

    def _read_chunks(self) -> list[tuple[bytes, Peer | None]]:
        self.flush()
        chunks: list[tuple[bytes, Peer | None]] = []
        for _ in range(MAX_READS_PER_POLL):
            try:
                data = os.read(self.port.fileno(), 4096)
            except BlockingIOError:
                break
            if not data:
                break
            chunks.append((data, None))
        return chunks

    def flush(self) -> None:
        """Write what earlier writes left behind (the port was full)."""
        while self._pending:
            try:
                n = os.write(self.port.fileno(), self._pending)
            except BlockingIOError:
                return
            del self._pending[:n]

    def _write(self, data: bytes, peer: Peer | None) -> bool:
        self.flush()
        if len(self._pending) + len(data) > SERIAL_TX_BUFFER:
            return False
        self._pending += data
        self.flush()
        return True

    def close(self) -> None:
        super().close()
        self.port.close()


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


_KINDS: dict[str, type[Endpoint]] = {"udpin": UdpInEndpoint, "udpout": UdpOutEndpoint, "serial": SerialEndpoint}


def open_endpoint(
    url: str, sysid: int = 1, compid: int = OWN_COMPONENT, signing: SigningConfig | None = None, link_id: int = 0
) -> Endpoint:
    """Open one endpoint from its URL (ValueError with a one-line message if it cannot be)."""
    parsed = parse_endpoint_url(url)
    return _KINDS[parsed.kind](parsed, sysid, compid, signing, link_id)


@dataclass(frozen=True)
class Received:
    """A message for local processing and where it came from (endpoint name, udpin peer)."""

    endpoint: str
    peer: Peer | None
    message: mavlink.MAVLink_message


def _target(msg: mavlink.MAVLink_message) -> tuple[int, int]:
    """(target_system, target_component) of a message, 0 where the field is absent."""
    system = getattr(msg, "target_system", 0) if "target_system" in msg.fieldnames else 0
    component = getattr(msg, "target_component", 0) if "target_component" in msg.fieldnames else 0
    return int(system), int(component)


class Router:
    """Several endpoints, one identity (sysid, compid 1), MAVLink routing between them."""

    def __init__(
        self, urls: Sequence[str], sysid: int = 1, compid: int = OWN_COMPONENT, signing: SigningConfig | None = None
    ) -> None:
        if isinstance(sysid, bool) or not isinstance(sysid, int) or not 1 <= sysid <= 255:
            raise ValueError(f"sysid must be an integer in 1..255, got {sysid!r}")
        if not urls:
            raise ValueError("at least one endpoint is needed")
        if len(set(urls)) != len(urls):
            raise ValueError("an endpoint is listed twice")
        self.sysid, self.compid = sysid, compid
        self.endpoints: dict[str, Endpoint] = {}
        self.routes: dict[tuple[int, int], LinkKey] = {}  # (sysid, compid) -> link it was last seen on
        self._selector = selectors.DefaultSelector()
        try:
            for link_id, url in enumerate(urls):
                endpoint = open_endpoint(url, sysid, compid, signing, link_id)
                self.endpoints[endpoint.name] = endpoint
                self._selector.register(endpoint.fileno(), selectors.EVENT_READ, endpoint)
        except BaseException:
            self.close()
            raise

    def __enter__(self) -> Router:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for endpoint in self.endpoints.values():
            if not endpoint.closed:
                endpoint.close()
        self._selector.close()

    # -- receive ------------------------------------------------------------------------------
    def poll(self, timeout: float = 0.0) -> list[Received]:
        """Wait up to `timeout` s for input, read every ready endpoint, forward, return local messages."""
        local: list[Received] = []
        try:
            ready = self._selector.select(timeout)
        except (OSError, ValueError):
            return local
        for key, _ in ready:
            endpoint: Endpoint = key.data
            for msg, peer in endpoint.read():
                if self._route(endpoint, peer, msg):
                    local.append(Received(endpoint.name, peer, msg))
            if endpoint.closed:
                self._selector.unregister(key.fd)
        return local

    def _route(self, endpoint: Endpoint, peer: Peer | None, msg: mavlink.MAVLink_message) -> bool:
        """Learn, forward; True if the message is for local processing."""
        source: LinkKey = (endpoint.name, peer)
        if endpoint.is_peer(peer):  # never from a sender without a slot (an unsigned RADIO_STATUS)
            self.routes[(msg.get_srcSystem(), msg.get_srcComponent())] = source
        system, component = _target(msg)
        raw = bytes(msg.get_msgbuf())
        if system == 0:
            self._forward(raw, self._all_links(), source)
            return True
        if system != self.sysid:
            self._forward(raw, self._links_of(system, component), source)
            return False
        if component in (0, self.compid):
            return True
        links = self._links_of(system, component)
        if links:
            self._forward(raw, links, source)
            return False
        return True  # a component of ours nobody has seen: ours to handle

    def _forward(self, raw: bytes, links: Iterable[LinkKey], source: LinkKey) -> None:
        for name, peer in links:
            endpoint = self.endpoints[name]
            exclude = None
            if name == source[0]:  # same endpoint: only other peers of a udpin endpoint
                if endpoint.kind != "udpin" or (peer is not None and peer == source[1]):
                    continue
                exclude = source[1]
            if endpoint.write(raw, peer, exclude=exclude):
                endpoint.stats.forwarded += 1

    def _all_links(self) -> list[LinkKey]:
        return [(name, None) for name in self.endpoints]

    def _links_of(self, system: int, component: int) -> list[LinkKey]:
        if component:
            link = self.routes.get((system, component))
            if link is not None:
                return [link]
            if system == self.sysid:
                return []
        return sorted({link for (s, _), link in self.routes.items() if s == system}, key=repr)

    # -- send ---------------------------------------------------------------------------------
    def send(self, msg: mavlink.MAVLink_message) -> int:
        """Send one of our messages by the routing rules; returns the number of links reached."""
        system, component = _target(msg)
        links = self._all_links() if system == 0 else self._links_of(system, component)
        reached = 0
        for name, peer in links:
            endpoint = self.endpoints[name]
            if not endpoint.closed:
                reached += bool(endpoint.write(endpoint.pack(msg), peer))
        return reached

    def stats(self) -> dict[str, EndpointStats]:
        return {name: endpoint.stats for name, endpoint in self.endpoints.items()}
