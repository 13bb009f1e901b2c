"""MB90F549 CAN controller model behind an 82C250 on the simulated bus."""
from __future__ import annotations

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from can_bus.bits import BitTiming, frame_length_bits, wire_bits
from can_bus.bus import CanBus, ErrorState
from can_bus.frames import CanFrame
from can_bus.transceiver import Transceiver82C250
from firmware_model.mcu.can_controller import (
    AMS_ALL,
    AMS_AMR0,
    AMS_AMR1,
    AMS_FULL,
    CSR_HALT,
    CSR_NIE,
    CSR_NT,
    CSR_TOE,
    LEIR_RCE,
    LEIR_TCE,
    NS_ACTIVE,
    NS_BUS_OFF,
    NS_PASSIVE,
    NS_WARNING,
    CanController,
    btr_from_timing,
    timing_from_btr,
)
from firmware_model.mcu.scheduler import Scheduler

TPB = 32  # 500 kbit/s


def flen(f: CanFrame, ifs: bool = True) -> int:
    return frame_length_bits(f.id, f.data, f.rtr, include_ifs=ifs, dlc=f.dlc)


class Rig:
    """``n`` controllers, each behind its own 82C250, on one bus; records IRQs with ticks."""

    def __init__(self, n: int = 2, timing: BitTiming | None = None, start: bool = True) -> None:
        self.sched = Scheduler()
        self.bus = CanBus(self.sched, timing)
        self.log: list[tuple[CanFrame, int, int, object]] = []
        self.errs: list[tuple] = []
        self.bus.trace = lambda f, s, e, w: self.log.append((f, s, e, w))
        self.bus.error_trace = lambda *a: self.errs.append(a)
        self.ctrls: list[CanController] = []
        self.xcvrs: list[Transceiver82C250] = []
        self.irqs: list[tuple[str, str, int, int]] = []
        for i in range(n):
            c = CanController(self.sched, timing, name=f"CAN{i}")
            x = Transceiver82C250(self.bus, c, name=f"X{i}")
            c.enable_irq(tx=0xFFFF, rx=0xFFFF)
            c.on_tx_irq = self._rec(c, "tx")
            c.on_rx_irq = self._rec(c, "rx")
            c.on_status_irq = self._rec(c, "ns")
            if start:
                c.start()
            self.ctrls.append(c)
            self.xcvrs.append(x)

    def _rec(self, c, kind):
        return lambda v: self.irqs.append((c.name, kind, v, self.sched.now))

    def run(self, t: int) -> None:
        self.sched.run_until(t)

    def of(self, name: str, kind: str) -> list[tuple[int, int]]:
        return [(v, t) for n, k, v, t in self.irqs if n == name and k == kind]


# ---------------------------------------------------------------- registers
def test_reset_state_and_btr():
    sched = Scheduler()
    c = CanController(sched)
    assert c.CSR == CSR_HALT and c.halted and c.BVALR == c.TREQR == c.RCR == c.TCR == 0
    assert c.BTR == 0x3A01 == btr_from_timing(BitTiming())  # TS2=3, TS1=10, RSJ=0, PSC=1
    assert timing_from_btr(c.BTR) == BitTiming()
    c.BTR = btr_from_timing(BitTiming.from_bitrate(125_000))
    assert c.timing.ticks_per_bit == 128
    # BTR is writable only while halted; a bit time different from the bus's is refused.
    bus = CanBus(sched)
    Transceiver82C250(bus, c)
    with pytest.raises(ValueError):
        c.start()
    assert c.halted
    c.set_timing(BitTiming())
    c.start()
    assert c.CSR == CSR_TOE
    with pytest.raises(RuntimeError):
        c.BTR = 0x3A01


def test_btr_with_a_one_quantum_segment_is_refused_and_changes_nothing():
    """BTR = 0x0A01 is TS2 = 0 (a one-quantum phase-2 segment), 0x3001 is TS1 = 0: the fields
    hold them, the manual's conditions (TSEG1, TSEG2 >= 2 TQ) forbid them."""
    c = CanController(Scheduler())
    for bad in (0x0A01, 0x3001):
        with pytest.raises(ValueError, match="tseg"):
            c.BTR = bad
        assert c.BTR == 0x3A01 and c.timing == BitTiming()
    c.BTR = 0x1A01  # TS2 = 1: two quanta, allowed
    assert (c.timing.tseg1, c.timing.tseg2) == (11, 2)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 64), st.integers(1, 16), st.integers(1, 8), st.integers(1, 4))
def test_btr_round_trip(psc, ts1, ts2, sjw):
    assume(sjw <= ts1 and sjw <= ts2 and psc * (1 + ts1 + ts2) >= 16)
    assume(ts1 >= (5 if psc == 1 else 2) and ts2 >= 2)  # the manual's BTR conditions
    t = BitTiming(psc, ts1, ts2, sjw)
    assert timing_from_btr(btr_from_timing(t)) == t


def test_toe_off_sends_nothing():
    r = Rig(2, start=False)
    a, b = r.ctrls
    a.configure_tx(0, 0x100)
    a.transmit(0, b"\x01")
    a.CSR = CSR_NIE  # HALT cleared but TOE = 0: the TX pin is a port
    b.start()
    r.run(10_000)
    assert r.log == [] and a.TREQR == 1
    a.CSR = CSR_TOE
    r.run(20_000)
    assert [(f.id, s) for f, s, *_ in r.log] == [(0x100, 10_000)]


# ---------------------------------------------------------------- transmission
def test_lowest_buffer_first_not_lowest_id_and_exact_irq_ticks():
    r = Rig(2, start=False)
    a, b = r.ctrls
    a.configure_tx(2, 0x100)
    a.configure_tx(5, 0x050)
    a.configure_tx(9, 0x010)
    b.configure_rx(0, 0, AMS_ALL)
    for buf in (9, 5, 2):
        a.transmit(buf, bytes([buf]))
    assert a.TREQR == (1 << 2) | (1 << 5) | (1 << 9)
    b.start()
    a.start()
    r.run(100_000)
    f2, f5, f9 = (CanFrame(i, bytes([k])) for i, k in ((0x100, 2), (0x050, 5), (0x010, 9)))
    e2 = flen(f2, False) * TPB
    s5 = flen(f2) * TPB
    e5 = s5 + flen(f5, False) * TPB
    s9 = s5 + flen(f5) * TPB
    e9 = s9 + flen(f9, False) * TPB
    assert [(f, s, e) for f, s, e, _ in r.log] == [(f2, 0, e2), (f5, s5, e5), (f9, s9, e9)]
    assert r.of("CAN0", "tx") == [(2, e2), (5, e5), (9, e9)]
    assert r.of("CAN1", "rx") == [(0, e2), (0, e5), (0, e9)]
    assert a.TREQR == 0 and a.TCR == (1 << 2) | (1 << 5) | (1 << 9)
    assert a.LEIR == LEIR_TCE | 9 and b.LEIR == LEIR_RCE | 0
    assert a.frames_sent == 3 and b.read(0) == f9 and b.ROVRR == 1  # never read: overruns
    a.TCR = ~(1 << 5)  # clear by writing 0
    assert a.TCR == (1 << 2) | (1 << 9)


def test_lower_buffer_requested_mid_frame_waits_for_the_next_arbitration():
    r = Rig(2)
    a, b = r.ctrls
    a.configure_tx(3, 0x300)
    a.configure_tx(0, 0x400)
    a.transmit(3, b"x")
    r.run(10 * TPB)
    a.transmit(0, b"y")  # lower buffer (higher priority) but frame 3 is on the bus
    r.run(100_000)
    assert [f.id for f, *_ in r.log] == [0x300, 0x400]
    assert [v for v, _ in r.of("CAN0", "tx")] == [3, 0]


def test_interrupt_enables_gate_callbacks_not_flags():
    r = Rig(2)
    a, b = r.ctrls
    a.enable_irq(tx=0)
    b.enable_irq(rx=0b10)
    a.configure_tx(0, 0x123)
    b.configure_rx(0, 0x123)
    a.transmit(0)
    r.run(10_000)
    assert r.irqs == [] and a.TCR == 1 and b.RCR == 1
    assert b.take(0) == CanFrame(0x123) and b.RCR == 0


def test_cancel_before_during_and_after_error():
    r = Rig(2)
    a, b = r.ctrls
    xa = r.xcvrs[0]
    a.configure_tx(0, 0x100)
    # Not yet arbitrated: gone at once.
    a.transmit(0)
    assert a.cancel(0) is True and a.TREQR == 0
    r.run(5_000)
    assert r.log == []
    # On the bus: the cancel waits; the frame completes, so TC is set and the cancel is void.
    a.transmit(0, b"\x01")
    r.run(5_000 + 10 * TPB)
    assert a.cancel(0) is False and a.TCANR == 1
    r.run(20_000)
    assert len(r.log) == 1 and a.TCR == 1 and a.TREQR == 0 and a.TCANR == 0
    # On the bus and destroyed by an error: the cancel takes effect, no retransmission.
    a.clear_tc(0)
    r.bus.inject_bit_error(xa, 1)
    a.transmit(0, b"\x02")
    r.run(20_000 + 10 * TPB)
    assert a.cancel(0) is False
    r.run(40_000)
    assert len(r.log) == 1 and len(r.errs) == 1
    assert a.TREQR == 0 and a.TCANR == 0 and a.TCR == 0 and a.tec == 8


def test_transmit_errors_on_misuse():
    r = Rig(1)
    (a,) = r.ctrls
    with pytest.raises(RuntimeError):
        a.transmit(0)  # not a valid transmit buffer
    a.configure_tx(0, 0x100)
    a.transmit(0)
    with pytest.raises(RuntimeError):
        a.transmit(0)  # request already pending
    with pytest.raises(ValueError):
        a.configure_tx(16, 0x100)
    with pytest.raises(ValueError):
        a.configure_rx(1, 0x800)


def test_remote_frame_transmit_and_receive():
    r = Rig(2)
    a, b = r.ctrls
    b.configure_rx(4, 0x181)
    a.configure_tx(1, 0x181)
    a.transmit(1, b"\xAA\xBB")
    r.run(10_000)
    assert b.DTR[4][:2] == b"\xAA\xBB" and b.RRTRR == 0
    b.clear_rc(4)
    a.configure_tx(1, 0x181, rtr=True)
    a.transmit(1, dlc=4)
    r.run(20_000)
    assert r.log[-1][0] == CanFrame(0x181, rtr=True, dlc=4)
    assert b.read(4).rtr and b.RRTRR == 1 << 4 and b.DLCR[4] == 4
    assert b.DTR[4][:2] == b"\xAA\xBB"  # a remote frame leaves DTR unchanged


# ---------------------------------------------------------------- acceptance
def test_acceptance_exact_masks_accept_all_and_priority():
    r = Rig(2)
    a, b = r.ctrls
    b.set_masks(amr0=0x00F, amr1=0x700)
    b.configure_rx(0, 0x181)             # exact
    b.configure_rx(1, 0x0C0, AMS_AMR0)   # 0x0C0..0x0CF
    b.configure_rx(2, 0x005, AMS_AMR1)   # any of the top 3 bits: 0x005, 0x105, ... 0x705
    b.configure_rx(15, 0, AMS_ALL)       # everything else
    b.configure_tx(3, 0x181)             # a transmit buffer never receives
    assert b.AMSR == (AMS_AMR0 << 2) | (AMS_AMR1 << 4) | (AMS_ALL << 30)
    a.configure_tx(0, 0)
    expect = {0x181: 0, 0x0C3: 1, 0x0CF: 1, 0x0D3: 15, 0x605: 2, 0x606: 15, 0x180: 15}
    got = {}
    for can_id in expect:
        a.configure_tx(0, can_id)
        a.transmit(0)
        r.run(r.sched.now + 200 * TPB)
        (v, _), = r.of("CAN1", "rx")[-1:]
        got[can_id] = v
        assert b.take(v).id == can_id and b.IDR[v] == can_id
    assert got == expect and b.ROVRR == 0


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 0x7FF), st.integers(0, 0x7FF), st.integers(0, 0x7FF),
       st.sampled_from([AMS_FULL, AMS_ALL, AMS_AMR0, AMS_AMR1]))
def test_acceptance_rule(rx_id, code, mask, ams):
    r = Rig(2)
    a, b = r.ctrls
    b.set_masks(amr0=mask, amr1=~mask & 0x7FF)
    b.configure_rx(7, code, ams)
    a.configure_tx(0, rx_id)
    a.transmit(0)
    r.run(10_000)
    care = {AMS_FULL: 0x7FF, AMS_ALL: 0, AMS_AMR0: ~mask & 0x7FF, AMS_AMR1: mask}[ams]
    assert bool(b.RCR) == ((rx_id ^ code) & care == 0)


def test_overrun_single_buffer_and_multilevel_buffers():
    r = Rig(2)
    a, b = r.ctrls
    b.configure_rx(0, 0x181)
    b.configure_rx(3, 0x185)
    b.configure_rx(4, 0x185)  # same filter: a two-level buffer
    a.configure_tx(0, 0x181)
    a.configure_tx(1, 0x185)

    def send(buf, data):
        a.transmit(buf, data)
        r.run(r.sched.now + 200 * TPB)

    send(0, b"\x01")
    send(0, b"\x02")  # buffer 0 still unread: overwritten, ROVR0
    assert b.ROVRR == 1 and b.read(0).data == b"\x02" and b.overruns == 1
    b.ROVRR = 0
    b.take(0)
    send(0, b"\x03")
    assert b.ROVRR == 0 and b.read(0).data == b"\x03"
    send(1, b"\x10")
    send(1, b"\x11")  # buffer 3 full: goes to 4
    assert [v for v, _ in r.of("CAN1", "rx")[-2:]] == [3, 4] and b.ROVRR == 0
    send(1, b"\x12")  # both full: the lowest-priority one (4) is overwritten
    assert b.read(3).data == b"\x10" and b.read(4).data == b"\x12" and b.ROVRR == 1 << 4
    b.take(3)
    send(1, b"\x13")  # buffer 3 free again
    assert b.read(3).data == b"\x13"


def test_halted_controller_takes_no_frames():
    r = Rig(2)
    a, b = r.ctrls
    b.configure_rx(0, 0, AMS_ALL)
    b.halt()
    a.configure_tx(0, 0x10)
    a.transmit(0)
    r.run(10_000)
    # a halted controller takes no part in bus traffic: it does not acknowledge either, so
    # a's frame, with nobody else on the bus, ends in ACK errors and is sent again
    assert r.log == [] and b.RCR == 0 and a.tec > 0 and a.TREQR == 1
    b.start()
    r.run(200_000)
    assert len(r.log) == 1 and b.RCR == 1


# ---------------------------------------------------------------- errors, bus-off
def test_error_counters_and_node_status_visible_to_firmware():
    r = Rig(2)
    a, b = r.ctrls
    a.CSR = a.CSR | CSR_NIE
    b.CSR = b.CSR | CSR_NIE
    f = CanFrame(0x123, b"\x11\x22")
    n = len(wire_bits(f.id, f.data)) - 10  # stuffed SOF..CRC: the default injection bit + 1
    r.bus.inject_bit_error(r.xcvrs[0], count=12)
    a.configure_tx(0, f.id)
    a.transmit(0, f.data)
    r.run(1)
    while len(r.errs) < 3:
        r.sched.step()
    assert (a.tec, a.rec, b.tec, b.rec) == (24, 0, 0, 3)
    # RTEC: REC in bits 7-0, TEC in bits 15-8 (F2MC-16LX manual §16.3.4, Figure 16.3-7)
    assert a.RTEC == 24 << 8 and b.RTEC == 3 and a.node_status == NS_ACTIVE
    while len(r.errs) < 12:
        r.sched.step()
    flag12 = r.errs[-1][3]
    assert flag12 == r.errs[-1][2] + n * TPB
    assert a.tec == 96 and a.node_status == NS_WARNING and a.CSR & CSR_NT
    assert (a.CSR >> 8) & 3 == NS_WARNING
    assert r.of("CAN0", "ns") == [(NS_WARNING, flag12)]
    a.CSR = a.CSR & ~CSR_NT
    assert not a.CSR & CSR_NT
    r.run(10**6)
    # The 13th attempt succeeds: TEC 95, back to error active (NT again); b's REC 11.
    assert (a.tec, b.rec) == (95, 11) and a.node_status == NS_ACTIVE
    assert [v for v, _ in r.of("CAN0", "ns")] == [NS_WARNING, NS_ACTIVE]
    assert a.error_state is ErrorState.ACTIVE and r.of("CAN1", "ns") == []


def _bus_off_rig():
    r = Rig(2)
    a, b = r.ctrls
    a.CSR = a.CSR | CSR_NIE
    f = CanFrame(0x123, b"\x11\x22")
    r.bus.inject_bit_error(r.xcvrs[0], count=32)
    a.configure_tx(0, f.id)
    a.transmit(0, f.data)
    b.configure_rx(0, f.id)
    return r, a, b, f


def test_bus_off_halts_then_firmware_restart_and_bus_recovery():
    r, a, b, f = _bus_off_rig()
    restarts = []

    def isr(ns):
        r.irqs.append(("CAN0", "ns", ns, r.sched.now))
        if ns == NS_BUS_OFF:
            assert a.halted
            restarts.append(r.sched.now)
            a.start()  # clear HALT at once; the 128 x 11 recessive bits still have to pass

    a.on_status_irq = isr
    r.run(1)
    while len(r.errs) < 32:
        r.sched.step()
    flags = [e[3] for e in r.errs]
    idle = r.errs[-1][4]
    recovery = idle + 127 * 11 * TPB  # same numbers as the bare bus test
    assert (flags[15], flags[31], recovery) == (34784, 74208, 119456)
    # HALT was written 0, yet reads 1 until the controller has rejoined (the manual's node
    # status transition: bus-off, HALT = 1, until 128 x 11 recessive bits after the write)
    assert a.bus_off and a.node_status == NS_BUS_OFF and a.halted and a.TREQR == 1
    # RTEC's TEC byte holds at 255 while bus-off (the count is over 255: docs/fidelity.md)
    assert a.tec > 255 and a.RTEC >> 8 == 255
    r.run(recovery - 1)
    assert a.bus_off and a.halted and a.CSR & CSR_HALT and r.log == []
    r.run(recovery)
    assert not a.bus_off and not a.halted and not a.CSR & CSR_HALT
    r.run(recovery + 1000 * TPB)
    assert r.of("CAN0", "ns") == [(NS_WARNING, flags[11]), (NS_PASSIVE, flags[15]),
                                  (NS_BUS_OFF, flags[31]), (NS_ACTIVE, recovery)]
    assert restarts == [flags[31]]
    end = recovery + flen(f, False) * TPB
    assert [(x[0], x[1], x[2]) for x in r.log] == [(f, recovery, end)]
    assert r.of("CAN0", "tx") == [(0, end)] and r.of("CAN1", "rx") == [(0, end)]
    assert (a.tec, a.rec, a.node_status, a.bus_off) == (0, 0, NS_ACTIVE, False)


def test_bus_off_late_restart_counts_from_halt_clear():
    """The MB90F549 manual starts the 128 x 11 recessive-bit count when HALT is cleared. The
    model once counted from the error, so with the child's 100 ms restart it resumed at once,
    >= 2.8 ms early. Now the node stays bus-off on the bus until 128 occurrences of 11
    recessive bits have passed after the firmware cleared HALT: on an idle bus exactly
    128 x 11 = 1408 bit times (2.816 ms at 500 kbit/s), and only then does the frame go."""
    r, a, b, f = _bus_off_rig()
    r.run(1)
    while len(r.errs) < 32:
        r.sched.step()
    counted_from_error = r.errs[-1][4] + 127 * 11 * TPB
    r.run(counted_from_error + 5000)
    assert r.bus.error_state(r.xcvrs[0]) is ErrorState.BUS_OFF     # nothing counted yet
    assert a.halted and a.node_status == NS_BUS_OFF and (a.CSR >> 8) & 3 == 3 and r.log == []
    t = counted_from_error + 7000
    r.run(t)
    a.start()                                                     # HALT = 0 at tick t
    assert a.bus_off and a.node_status == NS_BUS_OFF
    back = t + 128 * 11 * TPB
    assert 128 * 11 * TPB / 16_000_000 == 0.002816                 # seconds at 500 kbit/s
    r.run(back - 1)
    assert a.bus_off and r.log == []
    r.run(back + 1000 * TPB)
    assert r.of("CAN0", "ns")[-1] == (NS_ACTIVE, back)
    assert [(x[0], x[1]) for x in r.log] == [(f, back)]



def test_nie_is_csr_bit_2_as_in_the_familys_header():
    """The MB90540/545 I/O header puts CSR0's NIE at bit 2 (0x0004); the model had 0x0002, so
    firmware ported from it would set a reserved bit and get no status interrupt. Writing
    bit 1 enables nothing and does not read back."""
    assert (CSR_HALT, CSR_NIE, CSR_TOE, CSR_NT) == (0x0001, 0x0004, 0x0080, 0x0400)
    for write, irq in ((0x0002, False), (CSR_NIE, True)):
        r, a, _, _ = _bus_off_rig()
        a.CSR = CSR_HALT | write            # (the rig had set NIE: start from this write)
        a.start()
        assert bool(a.CSR & CSR_NIE) is irq and not a.CSR & 0x0002
        seen = []
        a.on_status_irq = seen.append
        r.run(200_000)
        assert bool(seen) is irq and a.node_status == NS_BUS_OFF


def test_firmware_polling_halt_after_bus_off_waits_until_the_controller_has_rejoined():
    """The firmware for this CAN macro clears HALT and polls ``while (CSR0_HALT);``. The
    model's HALT read 0 the moment it was written, so the loop ended 1408 bit times before
    the controller was back on the bus. Polled every bit time from the write, HALT reads 1
    until NS is error active again, at 128 x 11 bit times on an idle bus, then 0."""
    r, a, _, f = _bus_off_rig()
    r.run(1)
    while len(r.errs) < 32:
        r.sched.step()
    t = r.errs[-1][4] + 10_000
    r.run(t)
    assert a.bus_off and a.CSR & CSR_HALT
    a.CSR = (a.CSR | CSR_TOE) & ~CSR_HALT            # HALT = 0: recovery starts
    polls = 0
    while a.CSR & CSR_HALT:                          # while (CSR0_HALT);
        assert a.node_status == NS_BUS_OFF and r.log == []
        polls += 1
        r.run(r.sched.now + TPB)
    assert polls == 128 * 11 and r.sched.now == t + 128 * 11 * TPB
    assert a.node_status == NS_ACTIVE and not a.bus_off
    r.run(r.sched.now + 1000 * TPB)
    assert [x[0] for x in r.log] == [f]              # and the pending frame goes


def test_the_childs_driver_restarts_after_bus_off_and_reads_halt_until_rejoined():
    """The firmware model's CAN driver (firmware_model/child.py) clears HALT 100 ms after a
    bus-off and does not poll: its requests wait in their buffers. With HALT reading 1 until
    the controller has rejoined, its restart still works: HALT reads 1 from the bus-off
    through the recovery, 0 once NS is no longer bus-off, and the child is back on the bus."""
    from firmware_model.mcu.can_controller import CSR_HALT as HALT
    from hil.sim.faults import parse_fault
    from hil.sim.world import SimConfig, World
    w = World(SimConfig(robots=(0, 1), duration=3.5, seed=1, can=True, load=1,
                        faults=(parse_fault("busoff:1@1"),)))
    driver = w.children[1].can
    c = driver.can
    w.run(16_000_000)
    seen = []
    while w.now < 54_000_000:                        # the bus-off comes with its first order
        w.run(w.now + 8_000)                         # every 0.5 ms
        seen.append((c.bus_off, bool(c.CSR & HALT), c.halted, c.frames_received))
    assert driver.bus_offs == 1
    off = [s for s in seen if s[0]]
    assert off and all(h and hh for _, h, hh, _ in off)     # HALT reads 1 all through
    after = seen[max(i for i, s in enumerate(seen) if s[0]) + 1:]
    assert after and not any(h or hh for _, h, hh, _ in after)
    assert after[-1][3] > off[-1][3]                 # it takes the submodules' frames again
