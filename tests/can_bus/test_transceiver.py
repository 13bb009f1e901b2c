"""Philips 82C250 transceiver model: Rs modes, slope -> loop delay -> late ACK, standby
wake-up, stuck TXD."""
from __future__ import annotations


import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from can_bus.bits import BitTiming, frame_length_bits, wire_bits
from can_bus.bus import CanBus, ErrorState
from can_bus.frames import CanFrame
from can_bus.physical import loop_delay_s, max_bus_length_m, prop_time_s
from can_bus.transceiver import (
    MAX_BITRATE,
    RsMode,
    Transceiver82C250,
    max_bitrate,
    slew_rate,
)
from firmware_model.mcu.can_controller import AMS_ALL, CSR_NIE, NS_PASSIVE, CanController
from firmware_model.mcu.scheduler import Scheduler

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
    assert x.mode is RsMode.SLOPE_CONTROL and x.max_bitrate == MAX_BITRATE  # 1 m bus
    x.set_mode(RsMode.STANDBY)
    assert x.mode is RsMode.STANDBY and x.rs_ohms == 68_000


def test_slope_figures_by_hand():
    # AN96116 eq. 4: SR = 2.5 V / (7.6e-3 us/kOhm * R); 7 V/us at 47 kOhm
    assert slew_rate(47_000) == pytest.approx(7.0, abs=0.01)
    assert slew_rate(24_000) == pytest.approx(13.7, abs=0.1)
    # high speed: the slower data-sheet edge, t_offRXD 150 ns
    assert loop_delay_s(0) == loop_delay_s(1_000) == pytest.approx(150e-9)
    # 140 kOhm: 2.3496 V/us a wire, 4.6992 V/us differential; the recessive edge falls from
    # 2.0 V to 0.5 V in 1.5 / 4.6992 us = 319.2 ns, after the 150 ns high-speed delay
    assert loop_delay_s(140_000) == pytest.approx(469.2e-9, abs=0.1e-9)
    assert loop_delay_s(130_000) == pytest.approx(446.4e-9, abs=0.1e-9)
    # the default 500 kbit/s timing: (11 - 1) quanta of 125 ns; 1 Mbit/s, 16 quanta: 62.5 ns
    assert prop_time_s(BitTiming()) == pytest.approx(1250e-9)
    assert prop_time_s(BitTiming(prescaler=1)) == pytest.approx(625e-9)
    # 140 kOhm with a high-speed peer: 1250 - 469.2 - 150 = 630.8 ns of cable, 10 ns/m
    assert max_bus_length_m(BitTiming(), 140_000) == pytest.approx(63.08, abs=0.01)
    # on 1 m the round trip is 629.2 ns; 16 quanta with 10 for it: 1006.7 ns a bit
    assert max_bitrate(140_000) == 993_324
    # on 60 m: 469.2 + 150 + 600 = 1219.2 ns -> 1950.7 ns a bit
    assert max_bitrate(140_000, 60.0) == 512_631
    assert max_bitrate(0) == max_bitrate(16_500) == MAX_BITRATE
    assert max_bitrate(0, 1.0, BitTiming(prescaler=4, tseg1=2, tseg2=2, sjw=2)) == 0  # no room left


RATES = [1_000_000, 500_000, 250_000, 125_000, 100_000, 50_000]


@settings(max_examples=60, deadline=None)
@given(st.integers(16_500, 140_000), st.sampled_from(RATES), st.integers(0, 200))
def test_slope_limit_agrees_with_max_bitrate(rs, rate, length):
    bus = CanBus(Scheduler(), BitTiming.from_bitrate(rate), length_m=length)
    x = Transceiver82C250(bus, rs_ohms=rs)
    assert x.slope_limited == (rate > x.max_bitrate)
    assert x.slope_limited == (x.loop_delay_s + 150e-9 + length * 10e-9 >
                               prop_time_s(bus.timing))
    x.set_mode(RsMode.HIGH_SPEED)
    assert x.slope_limited == (300e-9 + length * 10e-9 > prop_time_s(bus.timing))


def test_bus_length_decides_a_slow_slope():
    for length, limited in ((60.0, False), (65.0, True)):
        sched = Scheduler()
        bus = CanBus(sched, length_m=length)
        a, b = Transceiver82C250(bus, rs_ohms=140_000), Transceiver82C250(bus)
        assert a.slope_limited is limited and bus.ack_in_time(a, b) is not limited


def test_bad_length_and_loop_delay_are_refused():
    sched = Scheduler()
    for bad in (-1, "10", None, float("nan")):
        with pytest.raises(ValueError, match="length_m"):
            CanBus(sched, length_m=bad)
    bus = CanBus(sched)
    x = Transceiver82C250(bus)
    with pytest.raises(ValueError, match="loop delay"):
        bus.set_loop_delay(x, -1e-9)


def test_late_ack_active_then_passive_transmitter():
    # 1 Mbit/s, 16 quanta: a 625 ns budget; A's 140 kOhm slope and B's high-speed loop need
    # 629.2 ns on 1 m, so A never sees B's ACK in time (nor B A's).
    tpb = 16
    sched, bus, (a, b), (xa, xb), log, errs = rig(2, BitTiming(prescaler=1),
                                                  rs={0: 140_000})
    assert xa.slope_limited and not xb.slope_limited and not bus.ack_in_time(xa, xb)
    f = CanFrame(0x100, b"\x01\x02")
    n = nstuffed(f)
    a.transmit(0, f.data)
    sched.run_until(1)
    while len(errs) < 16:
        sched.step()
    # error-active: its flag destroys the frame for B too (REC + 1), 8 TEC an attempt,
    # the ACK error at the ACK slot (bit n + 1), the next SOF 17 bits after it
    starts = [k * (n + 19) * tpb for k in range(16)]
    assert [(e[0], e[2], e[3]) for e in errs] == [("ack", s, s + (n + 2) * tpb) for s in starts]
    assert log == [] and b.RCR == 0
    assert (bus.tec(xa), bus.rec(xb)) == (128, 16)
    assert bus.error_state(xa) is ErrorState.PASSIVE
    # error-passive: its flag is recessive, B takes the frame at its end; A keeps TEC 128 and
    # retries after its suspend-transmission bits, so B takes it again
    # (passive since its 16th error, it already waited 8 suspend bits before attempt 17)
    s16 = (16 * (n + 19) + 8) * tpb
    while len(log) < 3:
        sched.step()
    ends = [s16 + k * (n + 27) * tpb for k in range(3)]
    assert [(fr, st_, en) for fr, st_, en, _ in log] == [(f, s, s + (n + 10) * tpb) for s in ends]
    assert b.RCR == 1 << 15
    assert (bus.tec(xa), bus.rec(xb)) == (128, 13)
    assert [e[0] for e in errs[16:]] == ["ack"] * 3
    # high speed again: 300 ns + 10 ns fits; the next attempt is acknowledged
    xa.set_mode(RsMode.HIGH_SPEED)
    assert not xa.slope_limited
    sched.run_until(sched.now + 2000 * tpb)
    assert len(log) == 4 and len(errs) == 19 and bus.tec(xa) == 127
    assert a.TREQR == 0


def test_one_acknowledgement_in_time_is_enough():
    # A fast transmitter, a slow receiver (its ACK late) and a fast one (in time): no error.
    sched, bus, (a, b, c), (xa, xb, xc), log, errs = rig(3, BitTiming(prescaler=1),
                                                         rs={1: 140_000})
    a.transmit(0, b"\x01")
    sched.run_until(100_000)
    assert errs == [] and len(log) == 1 and b.RCR == c.RCR == 1 << 15
    # without the fast receiver, the fast transmitter sees B's ACK late
    xc.standby()
    a.transmit(0, b"\x02")
    sched.run_until(sched.now + 2_000)
    assert errs and errs[0][0] == "ack" and len(log) == 1


def test_slope_control_within_the_limit_transmits():
    sched, bus, (a, b), (xa, xb), log, errs = rig(2, BitTiming(prescaler=1), rs={0: 130_000})
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
    assert wire_bits(0x500, b"\x01")[:6] == [0, 1, 0, 1, 0, 0]    # by hand: SOF, 0x500 = 101 0...
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
    a.CSR = a.CSR | CSR_NIE

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


def test_a_transceiver_on_a_python_can_bus_has_no_simulated_physics_to_tell():
    # the bench's bridge (can_bus.bridge.PythonCanBus) has no loop-delay model: the 82C250 on
    # it must still build (rprs child --can), and answer with a 1 m bus
    import can

    from can_bus.bridge import PythonCanBus
    from firmware_model.mcu.scheduler import Scheduler as Sched
    raw = can.Bus(interface="virtual", channel="xcvr-test", receive_own_messages=False)
    bus = PythonCanBus(Sched(), raw)
    try:
        x = Transceiver82C250(bus, rs_ohms=140_000)
        assert x.max_bitrate == 993_324 and not x.slope_limited
        x.set_mode(RsMode.HIGH_SPEED)
        assert x.mode is RsMode.HIGH_SPEED
    finally:
        bus.close()


def test_the_controller_reads_its_error_state_through_the_simulated_bus():
    # The child's supervision asks the controller for the error state at every frame it
    # receives; the controller asks its transceiver, which asks the bus.
    sched, bus, (c,), (x,), log, errs = rig(1)
    assert c.error_state is ErrorState.ACTIVE is x.error_state()
    c.transmit(0, b"\x01")              # nobody to acknowledge: an ACK error each try, TEC + 8
    sched.run_until(sched.now + 20 * 100 * 32)
    assert len(errs) >= 16
    assert c.error_state is ErrorState.PASSIVE is x.error_state() is x.status().state


def test_the_controller_reads_its_error_state_through_python_can():
    # The python-can bridge once lacked CanBus.error_state, and every `rprs child --can`
    # process died at its first received frame; only the wall-clock tests showed it.
    import can

    from can_bus.bridge import PythonCanBus
    sched = Scheduler()
    bus = PythonCanBus(sched, can.Bus(interface="virtual", channel=f"xcvr-{id(sched)}"))
    try:
        c = CanController(sched)
        x = Transceiver82C250(bus, c)
        assert c.error_state is ErrorState.ACTIVE is x.error_state() is x.status().state
    finally:
        bus.close()


def test_the_python_can_bridge_answers_everything_a_transceiver_asks_of_its_bus():
    # Read from the transceiver's source: each ``bus.NAME`` it reads without a getattr
    # default must exist on the bridge as on the simulated bus (a missing one killed every
    # `rprs child --can` process once: error_state).
    import re
    from pathlib import Path

    import can_bus.transceiver as transceiver
    from can_bus.bridge import PythonCanBus
    source = Path(transceiver.__file__).read_text()
    names = set(re.findall(r"\bbus\.([a-z_]+)", source))     # self.bus.X and bus.X
    assert {"status", "error_state", "request", "frame_on_air", "tpb", "attach"} <= names
    # the Protocol that states it lists every one of them (and nothing the source never uses)
    declared = {n for n in dir(transceiver.TransceiverBus) if not n.startswith("_")} | \
        set(transceiver.TransceiverBus.__annotations__)
    assert declared == names
    import can
    bridge = PythonCanBus(Scheduler(), can.Bus(interface="virtual", channel=f"names-{id(names)}"))
    try:
        for bus in (CanBus(Scheduler()), bridge):
            missing = sorted(n for n in names if not hasattr(bus, n))
            assert not missing, f"{type(bus).__name__} lacks {missing}"
    finally:
        bridge.close()
