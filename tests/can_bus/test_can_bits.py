"""CAN 2.0A bit level: CRC-15, stuffing, exact frame lengths, bit timing."""
from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from can_bus.bits import (
    ERROR_FLAG_BITS,
    ERROR_FLAG_MAX_BITS,
    ERROR_FRAME_BITS,
    OVERLOAD_FRAME_BITS,
    BitTiming,
    StuffError,
    _length,
    _stuff_int,
    _wire,
    crc15,
    frame_bits,
    frame_length_bits,
    min_length_bits,
    stuff,
    stuff_count,
    unstuff,
    wire_bits,
    worst_case_length_bits,
)

bits_st = st.lists(st.integers(0, 1), max_size=200)
frames_st = st.tuples(
    st.integers(0, 0x7FF), st.binary(max_size=8), st.booleans()
).map(lambda t: (t[0], b"" if t[2] else t[1], t[2]))


def s2b(s: str) -> list[int]:
    return [int(c) for c in s.replace(" ", "")]


def b2s(bits) -> str:
    return "".join(map(str, bits))


def crc15_by_division(bits) -> int:
    """Second, independent CRC: remainder of M(x) * x^15 divided by the full 16-bit generator."""
    gen = 0xC599  # x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1
    reg = 0
    for b in list(bits) + [0] * 15:
        reg = (reg << 1) | b
        if reg & 0x8000:
            reg ^= gen
    return reg


# ---------------------------------------------------------------- CRC-15
def test_crc15_catalogue_check_value():
    # CRC-15/CAN in the CRC catalogue: poly 0x4599, init 0, check("123456789") = 0x059E.
    msg = [int(b) for c in b"123456789" for b in format(c, "08b")]
    assert crc15(msg) == 0x059E
    assert crc15_by_division(msg) == 0x059E


def test_crc15_hand_vectors():
    assert crc15([]) == 0
    assert crc15([0] * 20) == 0
    assert crc15([1]) == 0x4599  # one shift with the feedback bit set: the polynomial itself
    # [1, 0]: 0x4599 << 1 = 0x8B32 -> drop x^15 -> 0x0B32, feedback 1 -> ^ 0x4599 = 0x4EAB
    assert crc15([1, 0]) == 0x4EAB


@settings(max_examples=200)
@given(bits_st)
def test_crc15_matches_division_and_has_zero_residue(bits):
    c = crc15(bits)
    assert c == crc15_by_division(bits)
    assert 0 <= c < 1 << 15
    assert crc15(list(bits) + [(c >> i) & 1 for i in range(14, -1, -1)]) == 0


# ---------------------------------------------------------------- hand-checked frames
def test_id0_eight_zero_bytes_heavy_stuffing():
    # SOF..r0 = 15 zeros -> 3 stuff bits (00000 1 00000 1 00000 1); DLC 1000 continues the
    # stuff-1 run (2 ones) then 000; the first 2 data zeros close a 5-run -> stuff #4; the other
    # 62 zeros give 12 more (62 = 12*5 + 2). CRC = 0x145B = 001010001011011: the pending "00"
    # + "00" is a 4-run, no 5-run anywhere -> 16 stuff bits in total.
    fb = frame_bits(0x000, bytes(8))
    assert len(fb) == 34 + 64 == 98
    assert b2s(fb[:19]) == "0" + "0" * 11 + "0" + "00" + "1000"
    crc = int(b2s(fb[-15:]), 2)
    assert crc == 0x145B == crc15_by_division(fb[:-15])
    assert stuff_count(fb) == 16
    w = wire_bits(0x000, bytes(8))
    assert b2s(w) == (
        "00000 1 00000 1 00000 1 1000 00 1"
        + " 00000 1" * 12
        + " 00 001010001011011"
        + " 1 1 1 1111111"
    ).replace(" ", "")
    assert len(w) == 98 + 16 + 10 == 124
    assert frame_length_bits(0x000, bytes(8), include_ifs=False) == 124
    assert frame_length_bits(0x000, bytes(8)) == 127


def test_id7ff_remote_frame():
    # 0 + 11 ones + RTR 1: twelve ones -> 11111 0 11111 0 11; IDE r0 DLC0000 = 6 zeros -> 00000 1 0;
    # CRC 0x54EA = 101010011101010 has no 5-run: 3 stuff bits, 34 + 3 + 10 = 47 (+3 IFS = 50).
    fb = frame_bits(0x7FF, rtr=True)
    assert int(b2s(fb[-15:]), 2) == 0x54EA == crc15_by_division(fb[:-15])
    w = wire_bits(0x7FF, rtr=True)
    assert b2s(w) == "0 11111 0 11111 0 11 00000 1 0 101010011101010 1 1 1 1111111".replace(" ", "")
    assert frame_length_bits(0x7FF, rtr=True) == 50
    assert frame_length_bits(0x7FF, rtr=True, include_ifs=False) == 47


def test_remote_frame_dlc_argument():
    fb = frame_bits(0x123, rtr=True, dlc=8)
    assert len(fb) == 34  # a remote frame has no data field whatever its DLC
    assert b2s(fb[12:19]) == "1" + "00" + "1000"
    assert frame_bits(0x123, rtr=True, dlc=15)[15:19] == [1, 1, 1, 1]
    # Data frame with DLC 9..15 means 8 bytes (ISO 11898-1).
    assert len(frame_bits(0x10, bytes(8), dlc=12)) == 98


def test_published_minimum_length_frame_without_stuff_bits():
    # The textbook 8-byte frame length with no stuffing: 44 + 64 = 108 bits, 111 with IFS.
    data = bytes.fromhex("5555555555555509")
    fb = frame_bits(0x555, data)
    assert stuff_count(fb) == 0
    assert b2s(fb) == (
        "0 10101010101 0 0 0 1000 " + "01010101 " * 7 + "00001001 " + "110100110011110"
    ).replace(" ", "")
    assert frame_length_bits(0x555, data) == 111 == min_length_bits(8)
    assert min_length_bits(8, include_ifs=False) == 108


def test_worst_case_bounds():
    # Davis et al. 2007: 8n + 47 + floor((34 + 8n - 1) / 4), IFS included.
    assert worst_case_length_bits(8) == 135
    assert worst_case_length_bits(0) == 55
    assert [worst_case_length_bits(n) for n in range(9)] == [55, 65, 75, 85, 95, 105, 115, 125, 135]
    assert worst_case_length_bits(8, include_ifs=False) == 132
    assert worst_case_length_bits(15) == 135
    # The bound is exactly what stuffing yields for the worst pattern 00000 1111 0000 1111 ...
    for n in range(9):
        g = 34 + 8 * n
        pattern = ([0] * 5 + ([1] * 4 + [0] * 4) * 20)[:g]
        assert stuff_count(pattern) == (g - 1) // 4 == worst_case_length_bits(n, False) - 44 - 8 * n


@settings(max_examples=150)
@given(frames_st)
def test_every_frame_between_min_and_worst_case(fr):
    can_id, data, rtr = fr
    n = frame_length_bits(can_id, data, rtr)
    dlc = 0 if rtr else len(data)
    size = 0 if rtr else len(data)
    assert min_length_bits(size) <= n <= worst_case_length_bits(size)
    assert n == 47 + 8 * size + stuff_count(frame_bits(can_id, data, rtr, dlc))
    w = wire_bits(can_id, data, rtr)
    assert len(w) + 3 == n
    assert unstuff(w[:-10]) == frame_bits(can_id, data, rtr)
    assert w[-10:] == [1] * 10


def test_error_and_overload_constants():
    assert ERROR_FLAG_BITS == 6 and ERROR_FLAG_MAX_BITS == 12
    assert ERROR_FRAME_BITS == 14 == OVERLOAD_FRAME_BITS


# ---------------------------------------------------------------- stuffing
def test_stuff_examples():
    assert stuff([0] * 5) == [0] * 5 + [1]
    assert stuff([0] * 4) == [0] * 4
    # The stuff bit starts the next run: 00000 (1) 1111 (0) ...
    assert b2s(stuff(s2b("00000 1111 0000"))) == "00000 1 1111 0 0000 1".replace(" ", "")
    assert stuff([1] * 10) == [1] * 5 + [0] + [1] * 5 + [0]


def test_unstuff_errors():
    with pytest.raises(StuffError) as ei:
        unstuff([0] * 6)
    assert ei.value.index == 5 and ei.value.value == 0
    with pytest.raises(StuffError):
        unstuff(s2b("0 11111 1"))
    assert unstuff(s2b("00000 1 0")) == [0] * 6
    assert isinstance(StuffError(0, 0), ValueError)


@settings(max_examples=200)
@given(bits_st)
def test_stuff_round_trip(bits):
    s = stuff(bits)
    assert unstuff(s) == bits
    assert len(s) - len(bits) == stuff_count(bits)
    assert "000000" not in b2s(s) and "111111" not in b2s(s)


runs_st = st.lists(st.tuples(st.integers(0, 1), st.integers(1, 12)), max_size=30).map(
    lambda runs: [bit for bit, n in runs for _ in range(n)])


@settings(max_examples=300)
@given(st.one_of(bits_st, runs_st))
def test_stuffing_by_byte_tables_is_stuffing_bit_by_bit(bits):
    # the frame path stuffs a byte at a time from tables whose states carry the run across
    # chunks; long equal runs, runs of four right after a stuff bit and runs that straddle a
    # chunk's edge are where the two could part
    value = int("".join(map(str, bits)) or "0", 2)
    assert list(_stuff_int(value, len(bits))) == stuff(bits)


wire_args_st = st.one_of(
    st.tuples(st.integers(0, 0x7FF), st.just(b""), st.just(True), st.integers(0, 15)),
    st.binary(max_size=8).flatmap(lambda d: st.tuples(
        st.integers(0, 0x7FF), st.just(d), st.just(False),
        st.integers(8, 15) if len(d) == 8 else st.just(len(d)))),
    st.tuples(st.sampled_from([0, 0x7FF, 0x400, 0x3FF]),
              st.sampled_from([bytes(8), b"\xff" * 8, b"\x0f\xf0" * 4]),
              st.just(False), st.just(8)),
)


@settings(max_examples=300)
@given(wire_args_st)
def test_wire_from_integers_is_the_bit_by_bit_wire(args):
    can_id, data, rtr, dlc = args
    expected = tuple(stuff(frame_bits(can_id, data, rtr, dlc))) + (1,) * 10
    assert _wire.__wrapped__(can_id, data, rtr, dlc) == expected


@settings(max_examples=300)
@given(wire_args_st)
def test_length_counted_from_tables_is_the_wire_length(args):
    # the bus takes a frame's length from _length, which never builds the bits
    assert _length.__wrapped__(*args) == len(_wire.__wrapped__(*args))


# ---------------------------------------------------------------- validation
@pytest.mark.parametrize(
    "kwargs",
    [
        dict(can_id=-1),
        dict(can_id=0x800),
        dict(can_id=0x10, data=bytes(9)),
        dict(can_id=0x10, rtr=True, dlc=16),
        dict(can_id=0x10, rtr=True, dlc=-1),
        dict(can_id=0x10, data=b"\x01", rtr=True),
        dict(can_id=0x10, data=b"\x01\x02", dlc=3),
        dict(can_id=0x10, data=bytes(7), dlc=9),
    ],
)
def test_validation(kwargs):
    with pytest.raises(ValueError):
        frame_bits(**kwargs)


def test_validation_messages_and_worst_case_dlc():
    with pytest.raises(ValueError, match="0..0x7FF"):
        frame_length_bits(0x800)
    with pytest.raises(ValueError, match="at most 8"):
        wire_bits(1, bytes(9))
    with pytest.raises(ValueError):
        worst_case_length_bits(16)


# ---------------------------------------------------------------- bit timing
def test_bit_timing_default_500k():
    t = BitTiming()
    assert (t.prescaler, t.tseg1, t.tseg2, t.sjw) == (2, 11, 4, 1)
    assert t.tq_per_bit == 16
    assert t.ticks_per_bit == 32
    assert t.bitrate == 500_000
    assert t.sample_point == 0.75
    assert t.sample_point_ticks == 24


def test_bit_timing_other_rates():
    assert BitTiming.from_bitrate(1_000_000).ticks_per_bit == 16
    t = BitTiming.from_bitrate(125_000, tq_per_bit=16, sample_point=0.875)
    assert (t.prescaler, t.tseg1, t.tseg2, t.ticks_per_bit, t.bitrate) == (8, 13, 2, 128, 125_000)
    assert BitTiming(prescaler=64, tseg1=16, tseg2=8, sjw=4).ticks_per_bit == 64 * 25
    with pytest.raises(ValueError):
        BitTiming.from_bitrate(300_000)
    # exactly 1 Mbit/s from a clock of no whole number of MHz is allowed
    assert BitTiming(prescaler=1, tseg1=11, tseg2=4, tick_hz=16_000_000).bitrate == 1_000_000
    # impossible arguments: ValueError, as documented (ZeroDivisionError before)
    for args in ((0,), (500_000, 0), (-1,), (500_000, 16, 0.75, 1, 0)):
        with pytest.raises(ValueError, match="positive int"):
            BitTiming.from_bitrate(*args)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(prescaler=0),
        dict(prescaler=65),
        dict(tseg1=0),
        dict(tseg1=17),
        dict(tseg2=0),
        dict(tseg2=9),
        dict(sjw=0),
        dict(sjw=5),
        dict(tseg2=2, sjw=3),
        dict(prescaler=1, tseg1=4, tseg2=2),  # 7 ticks a bit: faster than 1 Mbit/s
        # a clock of no whole number of MHz: 14 ticks of 14.7456 MHz are 1.053 Mbit/s, and
        # 16 ticks of 16.5 MHz 1.031 Mbit/s (a check rounding tick_hz down let both pass)
        dict(prescaler=1, tseg1=9, tseg2=4, tick_hz=14_745_600),
        dict(prescaler=1, tseg1=11, tseg2=4, tick_hz=16_500_000),
        # One-quantum segments: the register fields hold them, the manual forbids them
        # (F2MC-16LX hardware manual ch. 21, BTR: TSEG1 >= 2 TQ, TSEG2 >= 2 TQ).
        dict(tseg1=1, tseg2=8),
        dict(tseg1=14, tseg2=1),
        dict(prescaler=4, tseg1=1, tseg2=2),
    ],
)
def test_bit_timing_validation(kwargs):
    with pytest.raises(ValueError):
        BitTiming(**kwargs)


def test_bit_timing_psc0_needs_five_quanta_in_tseg1():
    """With PSC = 0 (a quantum is one clock tick) the manual asks TSEG1 >= 5 TQ. On an 8 MHz
    clock, 1 + 4 + 3 = 8 ticks is a legal 1 Mbit/s bit time but TSEG1 = 4 is refused; the
    same bit time as 1 + 5 + 2 is accepted. With PSC = 1 a TSEG1 of 2 is fine."""
    with pytest.raises(ValueError, match="tseg1 >= 5"):
        BitTiming(prescaler=1, tseg1=4, tseg2=3, tick_hz=8_000_000)
    assert BitTiming(prescaler=1, tseg1=5, tseg2=2, tick_hz=8_000_000).bitrate == 1_000_000
    assert BitTiming(prescaler=2, tseg1=2, tseg2=5, tick_hz=16_000_000).bitrate == 1_000_000


def test_a_truthy_rtr_is_the_remote_bit_whatever_its_value():
    """``rtr=2`` shifted into the header set the identifier's last bit instead of RTR: the
    length and the wire bits were another frame's, where ``frame_bits`` made the remote one."""
    from can_bus.bits import frame_bits, frame_length_bits, stuff, wire_bits
    for can_id in (0x002, 0x100, 0x7FE):
        assert frame_length_bits(can_id, b"", rtr=2) == \
            frame_length_bits(can_id, b"", rtr=True) == \
            len(stuff(frame_bits(can_id, b"", rtr=2))) + 13
        assert wire_bits(can_id, b"", rtr=2) == wire_bits(can_id, b"", rtr=True)
