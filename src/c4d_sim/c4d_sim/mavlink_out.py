"""The external-pose emulator's MAVLink output: VISION_POSITION_ESTIMATE frames over UDP.

What: `VisionSender(url, sysid)` packs MAVLink 2 VISION_POSITION_ESTIMATE (pymavlink, common
dialect) as component MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY of the vehicle's system and sends each
frame as one datagram to `udpout:HOST:PORT` (default the bridge's listening endpoint,
udpin:127.0.0.1:14550). The socket is non-blocking and never read: a full buffer or a refused port
(bridge not running) costs one counted error, never a stall of the sim's executive.
Why its own socket and not the bridge's code: block packages do not import each other; the sim is
just another MAVLink component on the link, as a companion computer running VIO would be.
"""

from __future__ import annotations

import socket

from pymavlink.dialects.v20 import common as mavlink

from .external_pose import VisionPositionFields, parse_udpout

COMPONENT = mavlink.MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY  # 197


class VisionSender:
    """One UDP socket sending VISION_POSITION_ESTIMATE; counters `sent`, `errors`."""

    def __init__(self, url: str, sysid: int) -> None:
        self.address = parse_udpout(url)
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=COMPONENT)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.sent = self.errors = 0

    def encode(self, f: VisionPositionFields) -> bytes:
        """The MAVLink 2 frame of these fields (sequence number advances)."""
        msg = mavlink.MAVLink_vision_position_estimate_message(f.usec, f.x, f.y, f.z, f.roll, f.pitch, f.yaw,
                                                              f.covariance, f.reset_counter)
        return msg.pack(self.mav)

    def send(self, f: VisionPositionFields) -> None:
        try:
            self.sock.sendto(self.encode(f), self.address)
            self.sent += 1
        except OSError:  # no listener, buffer full: counted, the sim goes on
            self.errors += 1

    def close(self) -> None:
        self.sock.close()
