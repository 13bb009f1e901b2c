"""Coverage-guided fuzz target: the byte-at-a-time deframer (firmware_model.radio.deframer).

Run:  .venv/bin/python fuzz/fuzz_deframer.py -atheris_runs=100000 [CORPUS_DIR ...]

The input is decoded (atheris.FuzzedDataProvider) into a byte stream cut into arbitrary chunks,
each with its own start tick and byte spacing, sometimes followed by ``abort``. Wire bytes are a
mix of raw fuzz bytes, Header/End fragments and real frames (possibly sealed with a checksum,
one byte changed, or truncated), so the fuzzer reaches deep frame states quickly. Properties:

1. nothing raises (``feed``, ``feed_byte``, ``flush``, ``abort``);
2. bulk == byte at a time: ``feed(chunk, t0, dt)`` returns exactly the events of
   ``feed_byte(b_i, t0 + i*dt)`` for every byte followed by ``flush()``; the public state
   (``in_frame``, ``first``, ``last_tick``, ``buffered``) agrees after every chunk;
3. chunking changes no frame: a third deframer fed byte by byte with no flush in between reports
   the same FrameReceived/FrameFailed sequence (when there are no aborts);
4. every FrameReceived re-encodes to exactly the bytes that arrived from its ``first`` tick to
   its ``end`` tick, and ``parse_frame`` of those bytes gives the same Frame;
5. every byte is accounted for exactly once: garbage + good frames + the prefixes of failed
   frames (``error.offset`` bytes) + bytes still buffered == bytes fed.

The properties live in :func:`check_deframer` (plain arguments) and the decoder in
:func:`draw_plan` (any "source" with int/bool/pick/bytes/more), so
tests/firmware_model/radio/test_fuzz.py runs the same checks under hypothesis without atheris.
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _harness import atheris, instrumented  # noqa: E402  (atheris is optional)

with instrumented(__name__ == "__main__"):
    from firmware_model.radio.content import COMMANDS
    from firmware_model.radio.deframer import Deframer, FrameFailed, FrameReceived, Garbage
    from firmware_model.radio.frame import END, HEADER, MAX_CONTENT, Frame, parse_frame
    from firmware_model.radio.integrity import seal
    from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS

__all__ = [
    "FdpSource",
    "draw_wire",
    "draw_frame_bytes",
    "draw_plan",
    "check_deframer",
    "TestOneInput",
    "main",
]

MAX_CHUNKS = 24
MAX_CONTENTS = (MAX_CONTENT, 0, 1, 3, 12, 40, 99, 100, 9999)
DTS = (1, 2, 7, CHILD_BYTE_TICKS, PC_BYTE_TICKS)
GAPS = (1, 2, 5, CHILD_BYTE_TICKS, PC_BYTE_TICKS, 3 * CHILD_BYTE_TICKS, 1_000_000)
_NAMES = tuple(COMMANDS) + ("bogus", "Movex", "_")
_FRAGMENTS = (HEADER, HEADER[:1], HEADER[:2], END, END[:1], b"\x0f\x0f\x0a\x05", b"0000", b"9999")


# --------------------------------------------------------------------------------------------
# Sources: where the decisions come from (atheris bytes here, hypothesis draws in the tests)


class FdpSource:
    """Decisions from an atheris.FuzzedDataProvider."""

    def __init__(self, fdp) -> None:
        self.fdp = fdp

    def int(self, lo: int, hi: int) -> int:
        return self.fdp.ConsumeIntInRange(lo, hi)

    def bool(self) -> bool:
        return self.fdp.ConsumeBool()

    def pick(self, seq):
        return self.fdp.PickValueInList(list(seq))

    def bytes(self, max_len: int) -> bytes:
        return self.fdp.ConsumeBytes(self.fdp.ConsumeIntInRange(0, max_len))

    def more(self) -> bool:
        return self.fdp.remaining_bytes() > 0


# --------------------------------------------------------------------------------------------
# Wire bytes


def _arg_text(src) -> str:
    k = src.int(0, 5)
    if k == 0:
        return str(src.int(-9, 9))
    if k == 1:
        return str(src.int(0, 127))
    if k == 2:
        return f"{src.int(-999, 999)}.{src.int(0, 999):0{src.int(1, 3)}d}"
    if k == 3:
        return str(src.int(-(10**11), 10**12))
    if k == 4:
        return src.pick(("", "-", ".", "1.", "-0", "0.0000", "1e3", " 1"))
    return str(src.int(0, 99))


def draw_content(src) -> bytes:
    """Content that is often a valid command list, sometimes not (printable either way)."""
    if src.int(0, 7) == 0:  # printable noise
        return bytes(0x20 + b % 95 for b in src.bytes(48))
    parts = []
    for _ in range(src.int(0, 4)):
        name = src.pick(_NAMES)
        spec = COMMANDS.get(name)
        n = spec.arity if spec is not None and src.int(0, 7) else src.int(0, 3)
        parts.append(f"{name}({','.join(_arg_text(src) for _ in range(n))})")
    return "".join(parts).encode("ascii")


def draw_frame_bytes(src, *, sealed: bool | None = None) -> bytes:
    """An encoded frame from fuzzed fields: plain or sealed, then maybe damaged."""
    dst, sid, num, typ = src.int(0, 9), src.int(0, 6), src.int(0, 99), src.int(0, 9)
    body = draw_content(src)
    if sealed is None:
        sealed = src.bool()
    frame = seal(dst, sid, num, typ, body) if sealed else Frame(dst, sid, num, typ, body)
    data = frame.encode()
    damage = src.int(0, 5)
    if damage == 1:  # one byte changed
        i = src.int(0, len(data) - 1)
        data = data[:i] + bytes([src.int(0, 255)]) + data[i + 1:]
    elif damage == 2:  # cut short
        data = data[: src.int(0, len(data) - 1)]
    elif damage == 3 and len(body) > 0:  # one content byte flipped (still printable, CRC off)
        i = 12 + src.int(0, len(body) - 1)
        data = data[:i] + bytes([0x20 + (data[i] - 0x20 + src.int(1, 94)) % 95]) + data[i + 1:]
    return data


def draw_wire(src) -> bytes:
    """One segment of received bytes: raw fuzz, a Header/End fragment, or a (damaged) frame."""
    kind = src.int(0, 3)
    if kind == 0:
        return src.bytes(32)
    if kind == 1:
        return src.pick(_FRAGMENTS)
    return draw_frame_bytes(src)


def draw_plan(src) -> tuple[int, list[tuple[bytes, int, int, bool]]]:
    """(max_content, chunks); a chunk is (data, gap to its first byte, dt, abort after it)."""
    max_content = src.pick(MAX_CONTENTS)
    chunks = []
    while len(chunks) < MAX_CHUNKS and src.more():
        data = b"".join(draw_wire(src) for _ in range(src.int(0, 3)))
        gap = src.pick(GAPS)
        dt = src.pick(DTS)
        abort = src.int(0, 7) == 0
        chunks.append((data, gap, dt, abort))
    return max_content, chunks


# --------------------------------------------------------------------------------------------
# The properties


def _state(d: Deframer) -> tuple:
    return (d.in_frame, d.first, d.last_tick, d.buffered)


def check_deframer(max_content: int, chunks, byte_ticks: int = CHILD_BYTE_TICKS) -> list:
    """Assert the deframer properties (module docstring) on this input; returns the bulk events."""
    bulk = Deframer(max_content, byte_ticks)
    single = Deframer(max_content, byte_ticks)
    lazy = Deframer(max_content, byte_ticks)  # byte by byte, flushed only at the very end
    stream = bytearray()
    index: dict[int, int] = {}  # tick -> position in ``stream``
    all_bulk: list = []
    all_lazy: list = []
    aborted = False
    last = -1
    for data, gap, dt, abort in chunks:
        assert gap >= 1 and dt >= 1
        t0 = last + gap
        ev_bulk = bulk.feed(data, t0, dt)
        ev_single: list = []
        for i, b in enumerate(data):
            t = t0 + i * dt
            index[t] = len(stream)
            stream.append(b)
            ev_single += single.feed_byte(b, t)
            all_lazy += lazy.feed_byte(b, t)
        ev_single += single.flush()
        assert ev_bulk == ev_single, (ev_bulk, ev_single)
        assert _state(bulk) == _state(single)
        all_bulk += ev_bulk
        if data:
            last = t0 + (len(data) - 1) * dt
        if abort:
            now = last + 1
            last = now
            a, b = bulk.abort(now), single.abort(now)
            assert a == b
            lazy.abort(now)
            aborted = True
            if a is not None:
                all_bulk.append(a)
            assert _state(bulk) == _state(single)
    tail = bulk.flush()
    assert tail == single.flush()
    all_bulk += tail
    all_lazy += lazy.flush()

    # 3. chunking changes no frame
    if not aborted:
        frames = [e for e in all_bulk if not isinstance(e, Garbage)]
        assert frames == [e for e in all_lazy if not isinstance(e, Garbage)]

    # 4. frames re-encode to the bytes they came from
    raw = bytes(stream)
    for ev in all_bulk:
        if isinstance(ev, FrameReceived):
            seg = raw[index[ev.first]: index[ev.end] + 1]
            assert ev.frame.encode() == seg, (ev, seg)
            assert parse_frame(seg, max_content) == ev.frame
            assert ev.frame.length <= max_content

    # 5. every byte accounted for once
    used = 0
    for ev in all_bulk:
        if isinstance(ev, Garbage):
            assert ev.count >= 1 and ev.first <= ev.last
            used += ev.count
        elif isinstance(ev, FrameReceived):
            used += ev.frame.nbytes
        elif isinstance(ev, FrameFailed):
            used += ev.error.offset
        else:  # pragma: no cover
            raise AssertionError(f"unknown event {ev!r}")
    assert used + bulk.buffered == len(raw), (used, bulk.buffered, len(raw))
    return all_bulk


def TestOneInput(data: bytes) -> None:
    max_content, chunks = draw_plan(FdpSource(atheris.FuzzedDataProvider(data)))
    check_deframer(max_content, chunks)


def main(argv: list[str] | None = None) -> None:
    if atheris is None:
        sys.exit("atheris is not installed: .venv/bin/pip install atheris")
    atheris.Setup(sys.argv if argv is None else argv, TestOneInput)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
