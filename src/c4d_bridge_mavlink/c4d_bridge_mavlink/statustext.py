"""STATUSTEXT longer than one frame: MAVLink 2 chunking (`id` + `chunk_seq`).

What: `StatusTextChunker.messages(severity, text)` returns the STATUSTEXT messages that carry
`text` whole. A text that fits one frame (≤ 50 bytes of UTF-8) is one message with id 0 ("the
only chunk", shown at once). A longer one is split at character boundaries into ≤ 50-byte chunks
sharing one non-zero id (1..65535, wrapping, never 0) with chunk_seq 0, 1, ...; the receiver knows
the last chunk by its NUL padding, so a text whose last chunk fills all 50 bytes is followed by an
empty chunk. At most MAX_CHUNKS chunks are sent; a longer text is cut and ends with "...".
Why: a text field holds 50 characters; without chunking reasons and refusals were cut mid-word
(issue 14 item 15). Stock clients reassemble: MAVSDK, QGroundControl and MAVProxy by (sysid,
compid, id) (https://mavlink.io/en/messages/common.html#STATUSTEXT).
"""

from __future__ import annotations

from .signing import mavlink

TEXT_BYTES = 50  # STATUSTEXT.text: char[50], NUL-terminated unless full
MAX_CHUNKS = 8
ELLIPSIS = "..."


def split_utf8(text: str, size: int = TEXT_BYTES) -> list[bytes]:
    """`text` as UTF-8 pieces of at most `size` bytes, never splitting a character."""
    pieces: list[bytes] = []
    current = b""
    for char in text:
        encoded = char.encode("utf-8")
        if len(current) + len(encoded) > size:
            pieces.append(current)
            current = b""
        current += encoded
    if current or not pieces:
        pieces.append(current)
    return pieces


class StatusTextChunker:
    """STATUSTEXT messages of one sender; keeps the chunk id counter (one id per long text)."""

    def __init__(self, max_chunks: int = MAX_CHUNKS) -> None:
        self.max_chunks = max_chunks
        self.last_id = 0

    def _next_id(self) -> int:
        self.last_id = self.last_id % 65535 + 1
        return self.last_id

    def messages(self, severity: int, text: str) -> list[mavlink.MAVLink_statustext_message]:
        pieces = split_utf8(text)
        if len(pieces) == 1:
            return [mavlink.MAVLink_statustext_message(severity, pieces[0], 0, 0)]
        if len(pieces) > self.max_chunks or (len(pieces) == self.max_chunks and len(pieces[-1]) == TEXT_BYTES):
            room = self.max_chunks * TEXT_BYTES - len(ELLIPSIS) - 1  # the last chunk keeps its NUL terminator
            kept = b"".join(pieces)[:room].decode("utf-8", errors="ignore")
            pieces = split_utf8(kept + ELLIPSIS)
        if len(pieces[-1]) == TEXT_BYTES:
            pieces.append(b"")  # a full last chunk has no NUL: an empty chunk ends the text
        chunk_id = self._next_id()
        return [mavlink.MAVLink_statustext_message(severity, piece, chunk_id, seq) for seq, piece in enumerate(pieces)]

