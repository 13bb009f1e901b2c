"""Frame wire format (docs/protocol.md §3.1, paper Fig. 8)."""
from __future__ import annotations

import pickle

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.radio.errors import ContentError, FrameError, WireError
from firmware_model.radio.frame import (
    BROADCAST,
    CHILD_IDS,
    END,
    FATHER,
    FRAME_FORMAT,
    HEADER,
    MAX_CONTENT,
    ROBOT_IDS,
    Frame,
    FrameType,
    built_frame,
    field_at,
    frame_codec,
    parse_frame,
    parse_frame_cached,
)
from contents import frames as frame_strategy

SETTINGS = settings(max_examples=200, deadline=None)

frames = frame_strategy(80)

PAPER = Frame(dst=2, src=1, num=5, type=2, content=b"movex(10)")
PAPER_BYTES = b"\x0f\x0a\x05" + b"2" + b"1" + b"05" + b"2" + b"0009" + b"movex(10)" + b"\x17\x19"


def test_constants():
    assert HEADER == b"\x0f\x0a\x05" and END == b"\x17\x19"
    assert (BROADCAST, FATHER) == (7, 0)
    assert list(CHILD_IDS) == [1, 2, 3, 4, 5, 6] and list(ROBOT_IDS) == list(range(7))
    assert MAX_CONTENT == 562
    assert [t.value for t in FrameType] == [0, 1, 2, 3, 4, 5, 6]  # 5 BOOT, 6 JOIN
    assert FrameType.BROADCAST_INFO == 3 and FrameType.FAILURE == 4


def test_paper_example_exact_bytes():
    assert PAPER.encode() == PAPER_BYTES
    assert len(PAPER_BYTES) == PAPER.nbytes == 23
    assert PAPER.length == 9
    assert parse_frame(PAPER_BYTES) == PAPER
    assert PAPER.frame_type is FrameType.INSTRUCTION


def test_heartbeat_bytes():
    hb = Frame(dst=BROADCAST, src=3, num=99, type=FrameType.BROADCAST_INFO)
    assert hb.encode() == b"\x0f\x0a\x0573993" + b"0000" + b"\x17\x19"
    assert hb.nbytes == 14
    assert Frame(dst=1, src=0, num=0, type=9).frame_type is None


def test_construct_declaration_builds_and_parses():
    c = FRAME_FORMAT.parse(PAPER_BYTES)
    assert (c.dst, c.src, c.num, c.type, c.length, c.content) == (2, 1, 5, 2, 9, b"movex(10)")
    assert FRAME_FORMAT.build(dict(dst=2, src=1, num=5, type=2, content=b"movex(10)")) == \
        PAPER_BYTES


@SETTINGS
@given(frames)
def test_round_trip(frame):
    data = frame.encode()
    assert len(data) == frame.nbytes == 14 + frame.length
    assert data[:3] == HEADER and data[-2:] == END
    assert data[8:12] == b"%04d" % frame.length
    assert parse_frame(data, max_content=9999) == frame
    assert FRAME_FORMAT.build(FRAME_FORMAT.parse(data)) == data


@SETTINGS
@given(frames)
def test_the_compiled_codec_is_the_declaration(frame):
    """What encode and parse_frame run (construct's compiled FRAME_FORMAT) gives the bytes and
    the fields the declaration gives, and refuses what it refuses."""
    fields = dict(dst=frame.dst, src=frame.src, num=frame.num, type=frame.type,
                  content=frame.content)
    data = FRAME_FORMAT.build(fields)
    assert frame_codec().build(fields) == data == frame.encode()
    assert frame_codec().parse(data) == FRAME_FORMAT.parse(data)


@pytest.mark.parametrize("bad", [dict(dst=10, src=1, num=5, type=2, content=b""),
                                 dict(dst=1, src=7, num=5, type=2, content=b""),
                                 dict(dst=1, src=1, num=5, type=2, content=b"\x00")])
def test_the_compiled_codec_refuses_what_the_declaration_refuses(bad):
    for codec in (FRAME_FORMAT, frame_codec()):
        with pytest.raises(Exception) as ei:
            codec.build(bad)
        assert "ValidationError" in type(ei.value).__name__


def _err(data: bytes, **kw) -> FrameError:
    with pytest.raises(FrameError) as ei:
        parse_frame(data, **kw)
    return ei.value


def _put(data: bytes, i: int, b: int) -> bytes:
    return data[:i] + bytes([b]) + data[i + 1 :]


@pytest.mark.parametrize(
    "offset, byte, field",
    [
        (0, 0x00, "header"),
        (1, 0x0F, "header"),
        (2, 0x06, "header"),
        (3, ord("A"), "destination"),
        (4, ord("7"), "source"),
        (4, ord("9"), "source"),
        (5, ord(" "), "number"),
        (6, ord("x"), "number"),
        (7, ord("-"), "type"),
        (8, ord("a"), "length"),
        (11, 0x17, "length"),
        (12, 0x0F, "content"),
        (20, 0x7F, "content"),
        (21, 0x19, "end"),
        (22, 0x17, "end"),
    ],
)
def test_error_names_offset_and_field(offset, byte, field):
    err = _err(_put(PAPER_BYTES, offset, byte))
    assert (err.offset, err.field, err.byte) == (offset, field, byte)
    assert str(err).startswith(f"byte {offset} ({field}): 0x{byte:02x}")


def test_error_message_example():
    err = _err(_put(PAPER_BYTES, 4, ord("9")))
    assert str(err) == "byte 4 (source): 0x39 '9' is not a robot ID '0'-'6'"
    assert isinstance(err, WireError) and isinstance(err, ValueError)
    assert not isinstance(err, ContentError)


def test_length_bound_reported_at_first_digit_that_exceeds_it():
    base = Frame(1, 0, 0, 2, b"").encode()
    # 0563 > 562: only the 4th digit makes it too big
    err = _err(base[:8] + b"0563" + b"x" * 563 + END)
    assert (err.offset, err.field, err.byte) == (11, "length", ord("3"))
    # 06..: already >= 600 at the 2nd digit
    err = _err(base[:8] + b"0600" + b"x" * 600 + END)
    assert (err.offset, err.field) == (9, "length")
    assert "0600" in str(err) and "562" in str(err)
    # 1...: >= 1000 at the 1st digit
    assert _err(base[:8] + b"1000").offset == 8
    # accepted when max_content allows it
    big = Frame(1, 0, 0, 2, b"y" * 600)
    assert parse_frame(big.encode(), max_content=600) == big
    assert _err(big.encode(), max_content=599).offset == 9  # "06" already >= 600
    assert _err(Frame(1, 0, 0, 2, b"y" * 563).encode()).offset == 11  # "0563"


def test_trailing_and_truncated():
    err = _err(PAPER_BYTES + b"\x0f")
    assert (err.offset, err.field, err.byte) == (23, "trailing", 0x0F)
    for n in range(len(PAPER_BYTES)):
        err = _err(PAPER_BYTES[:n])
        assert err.offset == n and err.byte is None
        assert err.field == field_at(n, 9 if n >= 12 else None)
        assert "truncated" in str(err)


@SETTINGS
@given(frames, st.sets(st.integers(0, 200), min_size=1, max_size=4))
def test_first_bad_byte_is_reported(frame, positions):
    data = frame.encode()
    positions = {p % len(data) for p in positions}
    bad = bytearray(data)
    for p in positions:
        bad[p] = 0x00  # invalid in every field
    err = _err(bytes(bad), max_content=9999)
    first = min(positions)
    assert err.offset == first and err.byte == 0
    assert err.field == field_at(first, frame.length)


@SETTINGS
@given(st.binary(max_size=64))
def test_parse_never_raises_anything_else(data):
    try:
        parse_frame(data)
    except FrameError as err:
        assert err.offset is not None and 0 <= err.offset <= len(data)


@pytest.mark.parametrize(
    "kw, field, offset",
    [
        (dict(dst=10), "destination", 3),
        (dict(dst=-1), "destination", 3),
        (dict(src=7), "source", 4),
        (dict(num=100), "number", 5),
        (dict(type=10), "type", 7),
        (dict(src=True), "source", 4),
        (dict(content=b"ab\ncd"), "content", 14),
        (dict(content="text"), "content", None),
        (dict(content=b"x" * 10000), "length", 8),
    ],
)
def test_frame_validation(kw, field, offset):
    args = dict(dst=1, src=0, num=0, type=2, content=b"")
    args.update(kw)
    with pytest.raises(FrameError) as ei:
        Frame(**args)
    assert (ei.value.field, ei.value.offset) == (field, offset)


def test_frame_accepts_bytearray_and_is_hashable():
    f = Frame(1, 2, 3, 4, bytearray(b"stop()"))
    assert f.content == b"stop()" and isinstance(f.content, bytes)
    assert hash(f) == hash(Frame(1, 2, 3, 4, b"stop()"))


def test_parse_frame_cached():
    a = parse_frame_cached(PAPER_BYTES)
    assert a == PAPER and parse_frame_cached(PAPER_BYTES) is a
    with pytest.raises(FrameError):
        parse_frame_cached(PAPER_BYTES[:-1])


@SETTINGS
@given(frames, st.integers(0, 100))
def test_built_frame_is_what_parsing_gives(frame, max_content):
    """Bytes built in this process are known without parsing: the frame given back is equal to
    what parse_frame gives, plain ints and bytes, and only if its Length fits ``max_content``."""
    data = frame.encode()
    got = built_frame(data, max_content)
    if frame.length <= max_content:
        assert got == parse_frame(data, max_content) == frame
        assert parse_frame_cached(data, max_content) == frame
        assert all(type(v) is int for v in (got.dst, got.src, got.num, got.type))
        assert type(got.content) is bytes
    else:
        assert got is None
        with pytest.raises(FrameError):
            parse_frame_cached(data, max_content)
    assert built_frame(data + b"x", 9999) is None and built_frame(data[:-1], 9999) is None


def test_built_frame_never_gives_an_enum_type_and_stays_bounded():
    """A frame built with a FrameType member is found as parse_frame gives it (plain ints),
    and the cache stays bounded."""
    import firmware_model.radio.frame as frame_module
    data = Frame(dst=7, src=6, num=98, type=FrameType.JOIN, content=b"enum(1)").encode()
    got = built_frame(data)
    assert got == Frame(7, 6, 98, 6, b"enum(1)") and type(got.type) is int
    assert parse_frame_cached(data) == Frame(7, 6, 98, 6, b"enum(1)")
    for i in range(2 * frame_module._CACHE_MAX + 10):
        Frame(dst=1, src=2, num=3, type=2, content=b"n(%d)" % i).encode()
    assert len(frame_module._BUILT) <= frame_module._CACHE_MAX
    assert len(frame_module._ENCODED) <= frame_module._CACHE_MAX
    assert len(frame_module._OLDER) <= frame_module._CACHE_MAX


def test_a_frame_sent_again_and_again_stays_found():
    """A frame encoded between thousands of others (a heartbeat among new messages) is found
    by its bytes every time it has just been encoded, whatever filled the cache before, and
    bytes kept and sent again without a new encode stay found while they are looked up: the
    flake of test_built_frame_is_what_parsing_gives, which failed when other tests had left
    the byte cache nearly full and a frame it had already encoded came again."""
    hot = Frame(dst=7, src=3, num=41, type=3, content=b"")
    sent_with_enum = Frame(dst=7, src=4, num=41, type=FrameType.BROADCAST_INFO, content=b"")
    kept = Frame(dst=7, src=5, num=12, type=3, content=b"")
    kept_bytes = kept.encode()        # a sender that keeps its heartbeat's bytes (the MAC)
    lost = []
    for i in range(12_000):           # three times the cache's generation of 4,096 frames
        Frame(dst=1, src=2, num=i % 100, type=2, content=b"m(%d)" % i).encode()
        for f in (hot, sent_with_enum):
            if built_frame(f.encode()) != f:
                lost.append((i, f))
        if i % 1000 == 999 and built_frame(kept_bytes) != kept:
            lost.append((i, kept))
    assert lost == []
def test_error_pickles_and_compares():
    err = _err(_put(PAPER_BYTES, 4, ord("9")))
    again = pickle.loads(pickle.dumps(err))
    assert again == err and str(again) == str(err) and hash(again) == hash(err)
    assert again.field == "source" and again.offset == 4 and again.byte == 0x39
