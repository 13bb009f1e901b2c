"""Bit-level UART reception when the sender's and the receiver's rates differ (issue 13: framing
errors from clock skew at the bit level), and the air faults that reach a receiver's UART.

The reference below is a second implementation written from the usual description of an 8N1
receiver, not from the model: it oversamples the line 16 times a bit, takes the first low
sample as the start edge, and reads each bit at the 8th of its 16 sub-samples.
"""
from __future__ import annotations

import random

import pytest

from firmware_model.mcu.uart import first_fall, rates_agree, sample_byte
from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS


def _waveform(values: list[int], tx_bt: int):
    """The line level at tick t for ``values`` sent back to back from tick 0."""
    def level(t: float) -> int:
        i, within = divmod(t, tx_bt)
        i = int(i)
        if i >= len(values):
            return 1
        bit = int(within * 10 // tx_bt)
        if bit == 0:
            return 0
        if bit == 9:
            return 1
        return (values[i] >> (bit - 1)) & 1
    return level


def _oversampling_receiver(values: list[int], tx_bt: int, rx_bt: int) -> list[tuple[int, bool]]:
    level = _waveform(values, tx_bt)
    tick = rx_bt / 160                          # one sub-sample: 1/16 of the receiver's bit
    end = len(values) * tx_bt + 2 * rx_bt
    out = []
    t = 0.0
    prev = 1
    while t < end:
        now = level(t)
        if prev == 1 and now == 0:              # a start edge
            start = t
            samples = [level(start + (16 * m + 8) * tick) for m in range(10)]
            if samples[0] == 0:
                value = sum(samples[m] << (m - 1) for m in range(1, 9))
                out.append((value, samples[9] == 0))
                t = start + (16 * 9 + 8) * tick  # ready again at the stop-bit sample
                prev = samples[9]
                continue
        prev = now
        t += tick
    return out


@pytest.mark.parametrize("skew", [0.0, 0.02, -0.03, 0.045])
def test_small_rate_differences_read_every_byte(skew):
    rx_bt = round(CHILD_BYTE_TICKS * (1 + skew))
    assert rates_agree(CHILD_BYTE_TICKS, rx_bt)
    rng = random.Random(1)
    for v in rng.sample(range(256), 40):
        assert sample_byte(v, CHILD_BYTE_TICKS, rx_bt, 0x55) == (v, False, True)


def test_the_father_and_the_children_read_each_other():
    assert rates_agree(CHILD_BYTE_TICKS, PC_BYTE_TICKS)
    assert rates_agree(PC_BYTE_TICKS, CHILD_BYTE_TICKS)


@pytest.mark.parametrize("skew", [0.06, 0.08, -0.06, -0.09])
def test_large_rate_differences_read_what_an_oversampling_uart_reads(skew):
    rx_bt = round(CHILD_BYTE_TICKS * (1 + skew))
    assert not rates_agree(CHILD_BYTE_TICKS, rx_bt)
    rng = random.Random(7)
    for _ in range(60):
        v = rng.randrange(256)
        ref = _oversampling_receiver([v], CHILD_BYTE_TICKS, rx_bt)
        got, framing, _ = sample_byte(v, CHILD_BYTE_TICKS, rx_bt)
        assert ref and (got, framing) == ref[0], (v, skew)


def test_a_slow_receiver_misses_the_next_start_edge():
    rx_bt = round(CHILD_BYTE_TICKS * 1.08)
    _, _, ready = sample_byte(0xA5, CHILD_BYTE_TICKS, rx_bt, 0x5A)
    assert not ready
    _, _, ready = sample_byte(0xA5, CHILD_BYTE_TICKS, rx_bt, None)
    assert ready                                 # nothing follows: nothing to miss


def test_a_fast_receiver_reads_the_last_data_bit_as_stop():
    rx_bt = round(CHILD_BYTE_TICKS * 0.93)      # stop sample at 8.8 sender bits: bit 7
    assert sample_byte(0x7F, CHILD_BYTE_TICKS, rx_bt)[1] is True     # MSB 0: framing error
    assert sample_byte(0xFF, CHILD_BYTE_TICKS, rx_bt)[1] is False


# -- the air: faults that reach a receiver's UART ---------------------------------------------


def _summary(*extra):
    from hil.sim.world import SimConfig, World
    from hil.cli.common import fault_spec
    w = World(SimConfig(robots=(0, 1, 2), duration=10, load=1.0, seed=3,
                        faults=tuple(fault_spec(f) for f in extra)))
    w.run()
    return w.summary()


def test_a_drop_fault_loses_bytes_without_byte_errors():
    """A regression: with no byte error rate, receptions took a fast path that skipped the
    drop fault, so ``drop@...`` did nothing."""
    clean = _summary()
    dropped = _summary("drop@1-9:0.05")
    bad = sum(v["bad_frames"] + v["refused_frames"] for v in dropped["robots"].values())
    assert sum(v["bad_frames"] for v in clean["robots"].values()) == 0
    assert bad > 0


def test_a_clock_far_off_garbles_that_robots_frames():
    s = _summary("skew:2:0.09")
    assert s["robots"][2]["mode"] == "listen" or s["robots"][2]["received"] == 0
    assert 2 not in s["robots"][1]["ring"]


# -- the falling edges INT0's flag sees (Uart.rx_fall) ------------------------------------

BT = CHILD_BYTE_TICKS


@pytest.mark.parametrize("value, edges", [
    (0x00, [0]),                         # start bit, then all zeros: one falling edge
    (0xFF, [0]),                         # all ones: the start bit's only
    (0x55, [0, 2, 4, 6, 8]),             # 1,0,1,0... LSB first: a fall before each 0
    (0x01, [0, 2]),                      # d0 = 1, d1 = 0
    (0x80, [0]),                         # a 1 only in the last data bit: no fall after it
    (0x0F, [0, 5]),                      # d3 = 1, d4 = 0
])
def test_the_falling_edges_of_a_byte_are_its_start_bit_and_each_one_to_zero_step(value, edges):
    start = 1000
    ticks = [start + i * BT // 10 for i in edges]
    got, after = [], -1
    while (t := first_fall(value, start, BT, after, start + BT)) is not None:
        got.append(t)
        after = t
    assert got == ticks


def test_an_edge_is_reported_only_inside_the_window_after_the_flag_was_cleared():
    start = 5000
    assert first_fall(0x00, start, BT, start - 1, start - 1) is None      # not begun by now
    assert first_fall(0x00, start, BT, start - 1, start) == start
    assert first_fall(0x00, start, BT, start, start + BT) is None         # cleared on its tick
    # the previous byte's handler cleared the flag after this start bit (back to back bytes):
    # the next edge the flag takes is a data bit's, and a byte with none sets no flag
    assert first_fall(0x55, start, BT, start + 10, start + BT) == start + 2 * BT // 10
    assert first_fall(0xFF, start, BT, start + 10, start + BT) is None
