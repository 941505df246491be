"""STATUSTEXT chunking: long texts travel whole as MAVLink 2 chunks; decoded by a stock pymavlink parser."""

from __future__ import annotations

import pytest

from c4d_bridge_mavlink.signing import make_mavlink, mavlink
from c4d_bridge_mavlink.statustext import MAX_CHUNKS, TEXT_BYTES, StatusTextChunker, split_utf8


def on_the_wire(messages) -> list:
    """Pack with our packer, parse with a fresh stock pymavlink parser (what a GCS decodes)."""
    sender = make_mavlink(1, 1)
    data = b"".join(m.pack(sender) for m in messages)
    return mavlink.MAVLink(None).parse_buffer(data) or []


def joined(received) -> str:
    """A GCS's reassembly: one id, chunk_seq order, ends at the first chunk that is not full."""
    ids = {m.id for m in received}
    assert len(ids) == 1
    assert [m.chunk_seq for m in received] == list(range(len(received)))
    assert all(len(m.text.encode()) == TEXT_BYTES for m in received[:-1]) and len(received[-1].text.encode()) < TEXT_BYTES
    return "".join(m.text for m in received)


def test_short_text_is_one_unchunked_message() -> None:
    (msg,) = on_the_wire(StatusTextChunker().messages(mavlink.MAV_SEVERITY_WARNING, "arming refused"))
    assert (msg.text, msg.id, msg.chunk_seq, msg.severity) == ("arming refused", 0, 0, mavlink.MAV_SEVERITY_WARNING)
    (full,) = on_the_wire(StatusTextChunker().messages(0, "x" * TEXT_BYTES))
    assert full.text == "x" * TEXT_BYTES and full.id == 0


@pytest.mark.parametrize("length", [51, 99, 100, 101, 150, 250])
def test_long_text_arrives_whole(length: int) -> None:
    text = "".join(chr(ord("a") + k % 26) for k in range(length))
    received = on_the_wire(StatusTextChunker().messages(mavlink.MAV_SEVERITY_INFO, text))
    assert joined(received) == text
    assert received[0].id != 0
    assert len(received) == length // TEXT_BYTES + 1  # a full last chunk is followed by an empty one


def test_ids_differ_between_texts_and_never_zero() -> None:
    chunker = StatusTextChunker()
    chunker.last_id = 65534
    ids = [chunker.messages(0, "y" * 60)[0].id for _ in range(3)]
    assert ids == [65535, 1, 2]


def test_utf8_is_split_between_characters() -> None:
    text = "é" * 40  # 80 bytes
    assert [len(p) for p in split_utf8(text)] == [50, 30]
    assert b"".join(split_utf8(text)).decode("utf-8") == text  # every piece decodes on its own too
    assert all(p.decode("utf-8") for p in split_utf8(text))
    assert [len(p) for p in split_utf8("a" + "é" * 25)] == [49, 2]


def test_too_long_text_is_cut_with_an_ellipsis() -> None:
    received = on_the_wire(StatusTextChunker().messages(0, "z" * 5000))
    text = joined(received)
    assert len(received) <= MAX_CHUNKS and text.endswith("...") and text.startswith("z" * 300)
