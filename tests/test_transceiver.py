"""Philips 82C250 transceiver model: Rs modes, slope limit, standby wake-up, stuck TXD."""
from __future__ import annotations

from fractions import Fraction

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from can_bus.bits import BitTiming, frame_length_bits, wire_bits
from can_bus.bus import CanBus, CanFrame, ErrorState
from can_bus.transceiver import (
    SLOPE_BITRATE_OHMS,
    RsMode,
    Transceiver82C250,
    max_bitrate,
    slew_rate,
)
from firmware_model.mcu.can_controller import AMS_ALL, NS_PASSIVE, CanController
from firmware_model.mcu.scheduler import Scheduler
from firmware_model.timing import TICK_HZ

TPB = 32  # 500 kbit/s


def flen(f: CanFrame, ifs: bool = True) -> int:
    return frame_length_bits(f.id, f.data, f.rtr, include_ifs=ifs, dlc=f.dlc)


def nstuffed(f: CanFrame) -> int:
    return len(wire_bits(f.id, f.data, f.rtr, f.dlc)) - 10


def rig(n=3, timing=None, rs=None):
    """``n`` running controllers (receive everything into buffer 15, transmit from buffer 0)."""
    sched = Scheduler()
    bus = CanBus(sched, timing)
    log, errs = [], []
    bus.trace = lambda f, s, e, w: log.append((f, s, e, w))
    bus.error_trace = lambda *a: errs.append(a)
    ctrls, xcvrs = [], []
    for i in range(n):
        c = CanController(sched, timing, name=f"CAN{i}")
        x = Transceiver82C250(bus, c, rs_ohms=(rs or {}).get(i, 0), name=f"X{i}")
        c.configure_rx(15, 0, AMS_ALL)
        c.configure_tx(0, 0x100 + i)
        c.start()
        ctrls.append(c)
        xcvrs.append(x)
    return sched, bus, ctrls, xcvrs, log, errs


# ---------------------------------------------------------------- Rs modes
def test_modes_and_resistor_ranges():
    sched = Scheduler()
    bus = CanBus(sched)
    assert Transceiver82C250(bus).mode is RsMode.HIGH_SPEED
    assert Transceiver82C250(bus, rs_ohms=1_000).mode is RsMode.HIGH_SPEED
    x = Transceiver82C250(bus, rs_ohms=47_000)
    assert x.mode is RsMode.SLOPE_CONTROL
    assert Transceiver82C250(bus, standby=True).mode is RsMode.STANDBY
    for bad in (5_000, 150_000, -1):
        with pytest.raises(ValueError):
            Transceiver82C250(bus, rs_ohms=bad)
    x.set_mode(RsMode.HIGH_SPEED)
    assert x.mode is RsMode.HIGH_SPEED and x.rs_ohms == 0
    with pytest.raises(ValueError):
        x.set_mode(RsMode.SLOPE_CONTROL)  # needs a slope resistor
    x.set_mode("slope-control", rs_ohms=68_000)
    assert x.mode is RsMode.SLOPE_CONTROL and x.max_bitrate == 257_352
    x.set_mode(RsMode.STANDBY)
    assert x.mode is RsMode.STANDBY and x.rs_ohms == 68_000


def test_slope_formula():
    assert max_bitrate(140_000) == 125_000  # the datasheet's slowest slope
    assert max_bitrate(47_000) == 372_340
    assert max_bitrate(17_500) == max_bitrate(16_500) == max_bitrate(0) == 1_000_000
    assert slew_rate(47_000) == pytest.approx(7.0, abs=0.01)  # AN96116: 7 V/us at 47 kOhm
    assert slew_rate(24_000) == pytest.approx(13.7, abs=0.1)


RATES = [1_000_000, 500_000, 250_000, 125_000, 100_000, 50_000]


@settings(max_examples=50, deadline=None)
@given(st.integers(16_500, 140_000), st.sampled_from(RATES))
def test_slope_limit_is_exact(rs, rate):
    bus = CanBus(Scheduler(), BitTiming.from_bitrate(rate))
    x = Transceiver82C250(bus, rs_ohms=rs)
    assert x.slope_limited == (Fraction(TICK_HZ, bus.tpb) > Fraction(SLOPE_BITRATE_OHMS, rs))
    x.set_mode(RsMode.HIGH_SPEED)
    assert not x.slope_limited


def test_slope_control_over_the_limit_gives_bit_errors():
    sched, bus, (a, b), (xa, xb), log, errs = rig(2, rs={0: 47_000})
    assert xa.slope_limited and xa.max_bitrate < 500_000
    f = CanFrame(0x100, b"\x01\x02")
    n = nstuffed(f)
    a.transmit(0, f.data)
    sched.run_until(1)
    while len(errs) < 3:
        sched.step()
    starts = [0, (n + 17) * TPB, 2 * (n + 17) * TPB]
    assert [(e[0], e[2], e[3]) for e in errs] == [("bit", s, s + n * TPB) for s in starts]
    assert (a.tec, b.rec, log) == (24, 3, [])
    # Switching to high speed mid-attempt: that attempt (already on the bus) still fails,
    # the next one goes through.
    s4 = 3 * (n + 17) * TPB
    sched.run_until(s4 + 10 * TPB)
    xa.set_mode(RsMode.HIGH_SPEED)
    sched.run_until(100_000)
    assert len(errs) == 4 and errs[3][2] == s4
    assert [(fr, s) for fr, s, *_ in log] == [(f, s4 + (n + 17) * TPB)]
    assert a.tec == 31  # 4 errors, 1 success


def test_slope_control_within_the_limit_transmits():
    sched, bus, (a, b), (xa, xb), log, errs = rig(2, BitTiming.from_bitrate(125_000),
                                                  rs={0: 140_000})
    assert not xa.slope_limited and xa.mode is RsMode.SLOPE_CONTROL
    a.transmit(0, b"\x01")
    sched.run_until(100_000)
    assert errs == [] and len(log) == 1 and b.RCR == 1 << 15


# ---------------------------------------------------------------- standby
def test_standby_no_transmission_no_reception_and_wake_at_sof():
    # (a third node, c, acknowledges b's frames: a, in standby, cannot)
    sched, bus, (a, b, c), (xa, xb, xc), log, errs = rig(3)
    wakes = []
    xa.on_wake = lambda t: wakes.append((t, sched.now))
    xa.standby()
    a.transmit(0, b"\xA0")
    sched.run_until(10_000)
    assert log == [] and a.TREQR == 1 and xa.mode is RsMode.STANDBY
    b.transmit(0, b"\xB0")  # SOF at 10 000
    sched.run_until(20_000)
    b.transmit(0, b"\xB1")
    sched.run_until(30_000)
    assert [(f.data, s) for f, s, *_ in log] == [(b"\xB0", 10_000), (b"\xB1", 20_000)]
    # once, 3 us (48 ticks) into the first frame's first dominant run that long: b's ID 0x101
    # sends SOF 0 then 0 0 1..., a run of 3 dominant bits (6 us) from the SOF
    assert wakes == [(10_048, 10_048)] and xa.wakeups == 1
    assert a.RCR == 0 and a.frames_received == 0  # nothing reaches the controller
    # Back to normal: a's pending frame goes at once; a receives again.
    xa.standby(False)
    sched.run_until(40_000)
    assert [(f.data, s) for f, s, *_ in log[2:]] == [(b"\xA0", 30_000)]
    b.transmit(0, b"\xB2")
    sched.run_until(50_000)
    assert a.read(15).data == b"\xB2"
    # A second standby period re-arms the wake-up.
    xa.standby()
    b.transmit(0, b"\xB3")
    sched.run_until(60_000)
    assert wakes[1] == (50_048, 50_048)


def test_standby_wakes_only_after_3_us_of_dominant_bus():
    """AN96116 §3.3: a dominant level of at least 3 us wakes the MCU through RxD; the model
    once woke on the SOF bit. At 500 kbit/s one dominant bit (2 us) is not enough: for ID
    0x500 the wire reads SOF 0, then 1 0 1 0 0 0..., so the first run of two or more dominant
    bits starts at bit 4, and the wake-up comes 48 ticks (3 us) into it."""
    from can_bus.bits import wire_bits
    sched, bus, (a, b, c), (xa, xb, xc), log, errs = rig(3)
    wakes = []
    xa.on_wake = lambda t: wakes.append(t)
    xa.standby()
    b.configure_tx(0, 0x500)
    assert wire_bits(0x500, b"\x01")[:6] == [0, 1, 0, 1, 0, 0]    # (checked independently)
    sched.run_until(10_000)
    b.transmit(0, b"\x01")                                      # SOF at 10 000
    sched.run_until(20_000)
    assert [s for _, s, *_ in log] == [10_000]
    assert wakes == [10_000 + 4 * 32 + 48]


def test_a_transceiver_in_standby_cannot_acknowledge():
    """Its transmitter is off (82C250 data sheet, standby): alone with a transmitter it leaves
    the ACK slot recessive, so the frame ends in an ACK error (the model once acknowledged
    through a transceiver in standby)."""
    sched, bus, (a, b), (xa, xb), log, errs = rig(2)
    xa.standby()
    b.transmit(0, b"\xB0")
    sched.run_until(20_000)
    assert log == [] and errs and all(e[0] == "ack" for e in errs)
    xa.standby(False)
    sched.run_until(200_000)
    assert [f.data for f, *_ in log] == [b"\xB0"]          # retransmitted, now acknowledged


def test_standby_wakes_on_a_stuck_bus():
    sched, bus, (a, b, c), (xa, xb, xc), log, errs = rig(3)
    wakes = []
    xa.on_wake = wakes.append
    xa.standby()
    H = 1000
    sched.run_until(H)
    xc.stick_txd()
    sched.run_until(H + 100 * TPB)
    assert bus.held and xa.rxd == 0 and xc.holding_bus
    assert wakes == [H + 6 * TPB]  # at the stuff-error flag (the bus's first hook)


# ---------------------------------------------------------------- stuck TXD
def test_stuck_txd_blocks_the_bus_until_standby_releases_it():
    sched, bus, (a, b, c), (xa, xb, xc), log, errs = rig(3)
    assert xa.rxd == 1
    H = 1000
    sched.run_until(H)
    xa.stick_txd(True)
    sched.run_until(H + 20 * TPB)
    b.transmit(0, b"\x0B")
    sched.run_until(H + 2000 * TPB)
    assert log == [] and bus.held and b.TREQR == 1  # nobody can send
    F = H + 6 * TPB
    # The receivers' counters climb (ISO rule for dominant bits after an error flag).
    assert b.node_status == NS_PASSIVE and c.node_status == NS_PASSIVE
    assert b.rec == 1 + 8 + 8 * (1 + (2000 - 6 - 14) // 8)
    assert c.error_state is ErrorState.PASSIVE
    # The faulty node's firmware switches its 82C250 to standby: the transmitter is off.
    R = H + 2000 * TPB + 5
    sched.run_until(R)
    xa.standby()
    sched.run_until(R + 1000 * TPB)
    idle = R + 11 * TPB
    fb = CanFrame(0x101, b"\x0B")
    end = idle + flen(fb, False) * TPB
    assert [(f, s, e) for f, s, e, _ in log] == [(fb, idle, end)]
    assert c.read(15) == fb and a.RCR == 0 and F < idle
    # Leaving standby with TXD still stuck holds the bus again; clearing the fault frees it.
    xa.standby(False)
    sched.run_until(sched.now + 500 * TPB)
    assert bus.held
    c.transmit(0, b"\x0C")
    sched.run_until(sched.now + 500 * TPB)
    assert len(log) == 1
    xa.stick_txd(False)
    sched.run_until(sched.now + 1000 * TPB)
    assert not bus.held and [f.id for f, *_ in log] == [0x101, 0x102]


def test_firmware_isolates_itself_from_its_status_interrupt():
    """The faulty node's ISR reacts to error passive by putting its 82C250 in standby (from
    inside the bus's callback): the others communicate again."""
    sched, bus, (a, b, c), (xa, xb, xc), log, errs = rig(3)
    a.CSR = a.CSR | 0x0002  # NIE

    def isr(ns):
        if ns >= NS_PASSIVE:
            xa.standby()

    a.on_status_irq = isr
    b.transmit(0, b"\x01")
    sched.run_until(2 * TPB)  # b's frame is on the bus when a's TXD sticks
    H = 2 * TPB
    xa.stick_txd()
    sched.run_until(H + 3000 * TPB)
    # Flag at H (frame in flight); 126 bits later every node is error-passive, a's ISR
    # releases the bus at that tick, the bus is idle 11 bits later and b, an error-passive
    # transmitter, retransmits after 8 more (suspend transmission).
    P = H + 126 * TPB
    fb = CanFrame(0x101, b"\x01")
    assert xa.mode is RsMode.STANDBY and not bus.held
    assert [(f, s) for f, s, *_ in log] == [(fb, P + (11 + 8) * TPB)]
    assert c.read(15) == fb
    assert b.tec == 8 + 8 * (1 + (126 - 14) // 8) - 1
