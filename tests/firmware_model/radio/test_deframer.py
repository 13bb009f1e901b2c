"""Byte-at-a-time deframer and its bulk fast path (docs/protocol.md §3.2)."""
from __future__ import annotations

import copy

from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.radio.deframer import Deframer, FrameFailed, FrameReceived, Garbage
from firmware_model.radio.errors import FrameError
from firmware_model.radio.frame import END, HEADER, Frame, field_at
from firmware_model.timing import CHILD_BYTE_TICKS
from contents import frames as frame_strategy

SETTINGS = settings(max_examples=200, deadline=None)
BT = CHILD_BYTE_TICKS

PAPER = Frame(dst=2, src=1, num=5, type=2, content=b"movex(10)")
HB = Frame(dst=7, src=3, num=0, type=3)

frames = frame_strategy(40)


def per_byte(d: Deframer, data: bytes, t0: int, dt: int) -> list:
    out = []
    for i, b in enumerate(data):
        out += d.feed_byte(b, t0 + i * dt)
    return out + d.flush()


def merge_garbage(events: list) -> list:
    out: list = []
    for e in events:
        if isinstance(e, Garbage) and out and isinstance(out[-1], Garbage):
            out[-1] = Garbage(out[-1].count + e.count, out[-1].first, e.last)
        else:
            out.append(e)
    return out


def of(events, kind):
    return [e for e in events if isinstance(e, kind)]


# ------------------------------------------------------------------ examples


def test_a_frame_built_here_is_known_before_any_deframer_parsed_it():
    """``known_frame`` takes bytes a sender of this process built (frame.built_frame) as one
    good frame, as ``feed`` would report it; a Length above the limit is left to ``feed``."""
    f = Frame(dst=4, src=2, num=77, type=2, content=b"built(%d)" % BT)
    data = f.encode()
    d = Deframer(max_content=1000)
    assert d.known_frame(data, 500) == f and d.last_tick == 500
    end = 100 + 10 * (len(data) - 1)
    assert Deframer(max_content=1000).feed(data, 100, 10) == [FrameReceived(f, 100, end)]
    small = Deframer(max_content=len(f.content) - 1)
    assert small.known_frame(data, 500) is None and small.last_tick is None
    assert of(small.feed(data, 0, 1), FrameFailed)


def test_single_frame_ticks():
    data = PAPER.encode()
    for feed in (lambda d: d.feed(data, 1000, BT), lambda d: per_byte(d, data, 1000, BT)):
        d = Deframer()
        ev = feed(d)
        assert ev == [FrameReceived(PAPER, 1000, 1000 + 22 * BT)]
        assert not d.in_frame and d.first is None and d.last_tick == 1000 + 22 * BT


def test_header_inside_partial_header():
    data = b"\x0f\x0f\x0a\x0f\x0a" + HB.encode()
    ev = Deframer().feed(data, 0, 1)
    assert ev == [Garbage(5, 0, 4), FrameReceived(HB, 5, 5 + 13)]
    ev = Deframer().feed(b"\x0f" + HB.encode(), 0, 1)  # 0F 0F 0A 05: header at offset 1
    assert ev == [Garbage(1, 0, 0), FrameReceived(HB, 1, 14)]


def test_bad_byte_fails_and_resyncs_on_it():
    data = PAPER.encode()
    bad = data[:15] + HB.encode()  # content cut short: HB's 0x0F is the bad byte
    ev = Deframer(byte_ticks=10).feed(bad, 0, 10)
    assert len(ev) == 2
    ff, fr = ev
    assert isinstance(ff, FrameFailed)
    assert (ff.error.offset, ff.error.field, ff.error.byte) == (15, "content", 0x0F)
    assert (ff.first, ff.at, ff.src, ff.length) == (0, 150, 1, 9)
    assert ff.expected_end == 0 + (13 + 9) * 10
    assert fr == FrameReceived(HB, 150, 150 + 130)


def test_failure_fields_before_length_known():
    ev = Deframer().feed(HEADER + b"29x", 0, 1)
    ff = ev[0]
    assert (ff.error.field, ff.error.offset, ff.src, ff.length, ff.expected_end) == \
        ("source", 4, None, None, None)
    assert ev[1:] == [Garbage(2, 4, 5)]  # '9' is re-hunted as garbage, then 'x'


def test_length_above_max_content():
    d = Deframer(max_content=20)
    ev = d.feed(Frame(1, 2, 3, 2, b"a" * 21).encode() + HB.encode(), 0, 1)
    ff = ev[0]
    # "0021" > 20
    assert (ff.error.field, ff.error.offset, ff.error.byte) == ("length", 11, ord("1"))
    assert isinstance(ev[-1], FrameReceived) and ev[-1].frame == HB
    ev = Deframer(max_content=600).feed(Frame(1, 2, 3, 2, b"a" * 600).encode(), 0, 1)
    assert ev[0].frame.length == 600


def test_bad_end():
    data = PAPER.encode()[:-1] + b"\x18"
    ff = Deframer(byte_ticks=1).feed(data, 0, 1)[0]
    assert (ff.error.field, ff.error.offset, ff.at, ff.expected_end) == ("end", 22, 22, 22)


def test_state_attributes_and_garbage_flush_rules():
    d = Deframer()
    assert (d.in_frame, d.first, d.last_tick, d.buffered) == (False, None, None, 0)
    assert d.feed_byte(ord("x"), 5) == []  # garbage is pending, not flushed by feed_byte
    assert d.flush() == [Garbage(1, 5, 5)] and d.flush() == []
    data = PAPER.encode()
    assert d.feed_byte(data[0], 10) == [] and not d.in_frame and d.first is None
    d.feed_byte(data[1], 11)
    assert not d.in_frame and d.buffered == 2
    d.feed_byte(data[2], 12)
    assert d.in_frame and d.first == 10 and d.last_tick == 12 and d.buffered == 3
    ev = d.feed(data[3:10], 13, 1)
    assert ev == [] and d.in_frame and d.first == 10 and d.last_tick == 19
    ev = d.feed(data[10:], 20, 1)
    assert ev == [FrameReceived(PAPER, 10, 32)]
    assert not d.in_frame and d.first is None and d.last_tick == 32


def test_abort():
    d = Deframer(byte_ticks=100)
    assert d.abort(0) is None
    data = PAPER.encode()
    d.feed(data[:14], 0, 100)
    ff = d.abort(5000)
    assert isinstance(ff, FrameFailed)
    assert (ff.error.field, ff.error.offset, ff.error.byte) == ("stall", 14, None)
    assert (ff.first, ff.at, ff.src, ff.length, ff.expected_end) == (0, 5000, 1, 9, 2200)
    assert not d.in_frame and d.first is None and d.last_tick == 1300
    assert d.abort(6000) is None
    assert d.feed(data, 10_000, 1) == [FrameReceived(PAPER, 10_000, 10_022)]
    # a partial header is dropped as garbage, not reported as a frame
    d.feed(b"\x0f\x0a", 20_000, 1)
    assert d.abort(30_000) is None and d.buffered == 0
    assert d.flush() == [Garbage(2, 20_000, 20_001)]
    # a frame aborted before Length completes
    d.feed(HEADER + b"21", 0, 1)
    ff = d.abort(9)
    assert (ff.src, ff.length, ff.expected_end, ff.error.offset) == (1, None, None, 5)


def test_reset():
    d = Deframer()
    d.feed(PAPER.encode()[:9], 0, 1)
    assert d.in_frame
    d.reset()
    assert (d.in_frame, d.first, d.last_tick, d.buffered) == (False, None, None, 0)
    assert d.feed(PAPER.encode(), 0, 1)[0].frame == PAPER


def test_feed_split_mid_frame_and_accepts_bytearray():
    data = PAPER.encode() + HB.encode()
    d = Deframer()
    ev = d.feed(bytearray(data[:7]), 0, 2) + d.feed(memoryview(data[7:]), 14, 2)
    assert ev == [FrameReceived(PAPER, 0, 44), FrameReceived(HB, 46, 46 + 26)]


# ------------------------------------------------------------------ resync properties

# Junk never contains 0x05 or 0x19, so no defect piece plus junk can ever complete a frame:
# the only frames on the wire are the good ones (see the module docstring of deframer.py).
junk = st.lists(st.integers(0, 255).filter(lambda b: b not in (0x05, 0x19)),
                min_size=1, max_size=30).map(bytes)


@st.composite
def defects(draw):
    frame = draw(frames)
    data = frame.encode()
    kind = draw(st.sampled_from(["partial", "truncated", "bad_end", "lying"]))
    if kind == "partial":
        return draw(st.sampled_from([b"\x0f", b"\x0f\x0a"]))
    if kind == "truncated":
        return data[: draw(st.integers(1, len(data) - 1))]
    if kind == "bad_end":
        end = draw(st.tuples(st.integers(0, 255), st.integers(0, 255))
                   .filter(lambda e: bytes(e) != END))
        return data[:-2] + bytes(end)
    lie = draw(st.integers(0, 9999).filter(lambda n: n != frame.length))
    return data[:8] + b"%04d" % lie + data[12:]


pieces = st.lists(
    st.one_of(frames.map(lambda f: ("good", f)), junk.map(lambda b: ("bad", b)),
              defects().map(lambda b: ("bad", b))),
    max_size=12,
)


def assemble(parts):
    data = bytearray()
    good = []
    for kind, p in parts:
        if kind == "good":
            good.append((p, len(data)))
            data += p.encode()
        else:
            data += p
    return bytes(data), good


@SETTINGS
@given(pieces, st.integers(0, 10**9), st.integers(1, 20_000))
def test_every_good_frame_found_once_in_order(parts, t0, dt):
    data, good = assemble(parts)
    d = Deframer(byte_ticks=dt)
    ev = d.feed(data, t0, dt)
    expected = [FrameReceived(f, t0 + off * dt, t0 + (off + f.nbytes - 1) * dt) for f, off in good]
    assert of(ev, FrameReceived) == expected
    assert per_byte(Deframer(byte_ticks=dt), data, t0, dt) == ev


@SETTINGS
@given(st.one_of(st.binary(max_size=200), pieces.map(lambda p: assemble(p)[0])),
       st.integers(0, 10**6), st.integers(1, 50))
def test_bulk_equals_byte_at_a_time(data, t0, dt):
    bulk = Deframer(byte_ticks=dt)
    ev = bulk.feed(data, t0, dt)
    one = Deframer(byte_ticks=dt)
    assert per_byte(one, data, t0, dt) == ev
    assert (bulk.in_frame, bulk.first, bulk.last_tick, bulk.buffered) == (
        one.in_frame,
        one.first,
        one.last_tick,
        one.buffered,
    )


@SETTINGS
@given(st.one_of(st.binary(max_size=200), pieces.map(lambda p: assemble(p)[0])),
       st.lists(st.integers(0, 200), max_size=6), st.integers(1, 50))
def test_chunked_feeds_equal_one_feed(data, cuts, dt):
    whole = Deframer().feed(data, 0, dt)
    d = Deframer()
    got = []
    bounds = sorted({0, len(data), *(c % (len(data) + 1) for c in cuts)})
    for a, b in zip(bounds, bounds[1:]):
        got += d.feed(data[a:b], a * dt, dt)
    assert merge_garbage(got) == merge_garbage(whole)
    # garbage runs split only at chunk ends, so merging restores the single-feed events
    assert merge_garbage(whole) == whole


@SETTINGS
@given(st.one_of(st.binary(max_size=300), pieces.map(lambda p: assemble(p)[0])), st.integers(1, 9))
def test_every_byte_accounted_for_and_never_raises(data, dt):
    d = Deframer(max_content=len(data) % 600)
    ev = d.feed(data, 0, dt)
    frames_bytes = sum(e.frame.nbytes for e in of(ev, FrameReceived))
    garbage = sum(e.count for e in of(ev, Garbage))
    failed = sum((e.at - e.first) // dt for e in of(ev, FrameFailed))
    assert frames_bytes + garbage + failed + d.buffered == len(data)
    for e in of(ev, FrameFailed):
        err = e.error
        assert isinstance(err, FrameError) and err.field == field_at(err.offset, e.length)
        assert err.byte == data[e.at // dt] and err.offset == (e.at - e.first) // dt
        if e.length is not None:
            assert e.expected_end == e.first + (13 + e.length) * d.byte_ticks
    for e in of(ev, Garbage):
        assert e.last - e.first == (e.count - 1) * dt


@SETTINGS
@given(st.lists(st.integers(-5, 300), max_size=100))
def test_feed_byte_never_raises(values):
    d = Deframer()
    for t, b in enumerate(values):
        d.feed_byte(b, t)
    d.abort(len(values))
    d.flush()


def _state(d: Deframer) -> dict:
    """Everything a deframer holds (its slots), the last frame's leftovers included."""
    return {k: (bytes(v) if isinstance(v, bytearray) else v)
            for k in type(d).__slots__ if hasattr(d, k) for v in (getattr(d, k),)}


@SETTINGS
@given(frames, st.lists(st.integers(0, 600), max_size=4), st.integers(1, 50),
       st.booleans())
def test_chunks_leave_the_state_byte_at_a_time_leaves(frame, cuts, dt, all_but_last):
    """Feeding a good frame in chunks (among them all but its last byte, as a receiver on the
    CPU model gets it: the End byte's handler runs apart) leaves the deframer, after every
    chunk, in the state its bytes one at a time leave it, the frame known or not; and reports
    the same."""
    data = frame.encode()
    n = len(data)
    bounds = {0, n, *(c % (n + 1) for c in cuts)}
    if all_but_last:
        bounds.add(n - 1)
    bounds = sorted(bounds)
    bulk, ref = Deframer(), Deframer()
    got, want = [], []
    for a, b in zip(bounds, bounds[1:]):
        got += bulk.feed(data[a:b], a * dt, dt)
        for i in range(a, b):
            want += ref.feed_byte(data[i], i * dt)
        want += ref.flush()
        assert _state(bulk) == _state(ref), (a, b)
    assert got == want and [type(e) for e in got] == [FrameReceived]


def test_a_frame_but_its_last_byte_takes_the_door_and_an_unknown_one_the_long_way():
    """The door for all but the last byte looks the frame up among those known (built here or
    seen whole): a frame of bytes nobody built takes the byte-at-a-time path, to the same
    state."""
    built = PAPER.encode()
    d = Deframer()
    assert d._all_but_last(built[:-1], 0, (len(built) - 2) * BT)
    forged = built.replace(b"movex(10)", b"movex(77)")
    assert not Deframer()._all_but_last(forged[:-1], 0, 0)
    a, b = Deframer(), Deframer()
    a.feed(forged[:-1], 0, BT)
    for i, x in enumerate(forged[:-1]):
        b.feed_byte(x, i * BT)
    assert _state(a) == _state(b)
    assert a.feed(forged[-1:], (len(forged) - 1) * BT, BT) == \
        [FrameReceived(Frame(dst=2, src=1, num=5, type=2, content=b"movex(77)"), 0,
                       (len(forged) - 1) * BT)]


@SETTINGS
@given(st.binary(max_size=40), frames, st.integers(1, 3))
def test_a_frame_taken_whole_leaves_what_feeding_it_leaves(before, f, split):
    """After whatever came before it (garbage, a broken frame, a frame cut short, once its
    bytes stopped), a good frame taken whole by ``known_frame`` (as an ideal receiver, or a
    CPU model's receiver given a frame's late bytes with its End) leaves the deframer as
    feeding it byte by byte, or in two chunks, does: nothing of the frames before it is
    left (Header tick, bytes, Source, Length)."""
    data = f.encode()
    states = []
    for how in ("whole", "per byte", "chunks"):
        d = Deframer()
        d.feed(before, 0, BT)
        d.abort(len(before) * BT)
        d.flush()                           # (what a receiver's feed reports at its end)
        t0 = (len(before) + 5) * BT
        end = t0 + (len(data) - 1) * BT
        if how == "whole":
            assert d.known_frame(data, end) == f
        elif how == "per byte":
            assert of(per_byte(d, data, t0, BT), FrameReceived)
        else:
            k = len(data) - split
            events = d.feed(data[:k], t0, BT) + d.feed(data[k:], t0 + k * BT, BT)
            assert of(events, FrameReceived)
        states.append(_state(d))
    assert states[0] == states[1] == states[2]


@st.composite
def fixed_field_splits(draw):
    """A Length limit, and a stream of frames (some with one Header or fixed-field byte
    replaced: a digit, a Header byte or any byte; some with a Source at the range's edge or
    past it, or another Length, at the limit or past it), with a partial Header or junk
    between them, and the chunk sizes (1-10 bytes, as a receiver on the CPU model gets them,
    and a few longer) to feed it in: chunks start anywhere in the Header and fixed fields."""
    # frames of longer Content fail at Length; a Length digit replaced may then fit a large limit
    max_content = draw(st.one_of(st.integers(0, 45), st.integers(1000, 9999)))
    data = bytearray(draw(st.sampled_from([b"", b"\x0f", b"\x0f\x0a", b"x\x0f"])))
    for f in draw(st.lists(frames, min_size=1, max_size=4)):
        b = bytearray(f.encode())
        how = draw(st.sampled_from(["good", "byte", "source", "length"]))
        if how == "byte":
            b[draw(st.integers(0, 11))] = draw(st.one_of(
                st.integers(0x30, 0x39), st.sampled_from(HEADER), st.integers(0, 255)))
        elif how == "source":                       # '6' the last good one
            b[4] = draw(st.sampled_from(b"6789"))
        elif how == "length":                       # a Length that may fit, and lie
            b[8:12] = b"%04d" % draw(st.one_of(
                st.integers(max(0, max_content - 1), min(9999, max_content + 1)),
                st.integers(0, max_content), st.integers(0, 9999)))
        data += b + draw(st.sampled_from([b"", b"\x0f", b"\x0f\x0a", b"\x0f\x0f\x0a", b"?"]))
    sizes = draw(st.lists(st.one_of(st.integers(1, 10), st.integers(11, 40)),
                          min_size=1, max_size=40))
    return max_content, bytes(data), sizes


def _live(d: Deframer) -> dict:
    """Every slot but those nothing reads before setting them afresh: the Header tick while
    hunting with no partial Header, the frame's bytes, Source, Length and partial Length while
    no frame is in progress (the hunt's bulk paths leave them as they were; a byte at a time
    may not)."""
    state = _state(d)
    if not d._pos:
        del state["_hdr_t"]
    if not d.in_frame:
        for k in ("_raw", "_src", "_len", "_partial"):
            del state[k]
    return state


@settings(max_examples=500, deadline=None)
@given(fixed_field_splits(), st.integers(1, 50))
def test_chunks_cut_in_the_fixed_fields_leave_what_bytes_one_at_a_time_leave(split, dt):
    """Chunks of 1-10 bytes starting anywhere in a frame's Header and fixed fields, the
    frame good or with a bad field byte (Source above 6, a Length over the limit...),
    report what its bytes one at a time report and leave the state they leave, after every
    chunk; and ``_advance`` over a chunk leaves every slot as ``_step`` on each byte does."""
    max_content, data, sizes = split
    bulk, ref = Deframer(max_content=max_content), Deframer(max_content=max_content)
    a = k = 0
    while a < len(data):
        b = min(len(data), a + sizes[k % len(sizes)])
        k += 1
        fast, slow = copy.deepcopy(bulk), copy.deepcopy(bulk)
        fast_out: list = []
        slow_out: list = []
        i = a
        while i < b:
            i = fast._advance(data[:b], i, 0, dt, fast_out)
        for i in range(a, b):
            slow._step(data[i], i * dt, slow_out)
        assert fast_out == slow_out and _state(fast) == _state(slow), (a, b)
        got = bulk.feed(data[a:b], a * dt, dt)
        want = []
        for i in range(a, b):
            want += ref.feed_byte(data[i], i * dt)
        want += ref.flush()
        assert got == want, (a, b)
        assert _live(bulk) == _live(ref), (a, b)
        a = b


def test_fixed_fields_are_taken_without_a_call_a_byte(monkeypatch):
    """A frame's Header and fixed fields cut in chunks are taken in one go per chunk (no
    ``_step`` call), Source and Length at their limits, to the state its bytes one at a time
    leave, the garbage before the Header reported; a bad Source byte goes the byte-at-a-time
    way and is reported at its offset."""
    f = Frame(dst=9, src=6, num=99, type=9, content=b"edge(1234)")
    data = f.encode()
    limit = len(f.content)
    ref = Deframer(max_content=limit)
    want = per_byte(ref, b"junk", -4 * BT, BT)
    for i, b in enumerate(data[:12]):
        want += ref.feed_byte(b, i * BT)

    def no_step(*args):
        raise AssertionError("_step called")
    monkeypatch.setattr(Deframer, "_step", no_step)
    d = Deframer(max_content=limit)
    got = d.feed(b"junk" + data[:5], -4 * BT, BT)
    got += d.feed(data[5:9], 5 * BT, BT) + d.feed(data[9:12], 9 * BT, BT)
    monkeypatch.undo()
    assert got == want == [Garbage(4, -4 * BT, -BT)]
    assert _state(d) == _state(ref) and (d._src, d._len, d.in_frame) == (6, limit, True)
    bad = data[:4] + b"7" + data[5:]
    d = Deframer()
    ev = d.feed(bad[:3], 0, BT) + d.feed(bad[3:8], 3 * BT, BT)
    assert [type(e) for e in ev] == [FrameFailed, Garbage]
    assert ev[0].error.offset == 4 and ev[0].at == 4 * BT and ev[0].error.field == "source"
