"""Errors one node alone sees (a disturbance on its stub): ISO 11898-1 error signalling with
overlapping flags and the receiver rule "+8 for a dominant bit right after its own flag"
(issue 13, CAN item 7).

The expectations are worked here from the standard's rules, not from the bus model: the node
that sees the error sends 6 dominant bits from the next bit; a transmitter detects a bit
error at its first recessive bit read dominant; every other receiver a stuff error at the
sixth equal bit in a row (or a form error at a dominant CRC delimiter) and sends its own flag;
the flags end at the last one, then 8 delimiter bits and 3 of intermission. Wire bits come
from can_bus.bits, which tests/can_bus/test_can_bits.py checks bit by bit against the standard's
rules and tests/can_bus/test_frame_length_canbusload.py against can-utils' canbusload (exact
stuffing).
"""
from __future__ import annotations

from can_bus.bits import wire_bits
from can_bus.bus import ErrorState
from can_bus.frames import CanFrame

from can_testbed import TPB, make

FRAME = CanFrame(0x101, bytes.fromhex("0011223344556677"))


def signalling(frame: CanFrame, b: int):
    """(transmitter's detection bit, other receivers' bit, last flag bit) for an error seen
    by one receiver at wire bit ``b``, worked from the rules above."""
    wire = wire_bits(frame.id, frame.data, frame.rtr, frame.dlc)
    n = len(wire) - 10                                  # SOF..CRC, stuffed
    d_tx = next(i for i in range(b + 1, len(wire)) if wire[i] == 1)
    run = 0
    for i in range(b, -1, -1):
        if wire[i] != 0:
            break
        run += 1
    d_rx = min(b + 6 - run, n)
    return d_tx, d_rx, max(b, d_tx, d_rx) + 6, wire, n


def test_a_local_error_at_a_recessive_bit_makes_a_twelve_bit_flag():
    wire = wire_bits(FRAME.id, FRAME.data, FRAME.rtr, FRAME.dlc)
    b = next(i for i in range(30, len(wire) - 16) if wire[i] == 1 and wire[i + 1] == 1)
    d_tx, d_rx, end, _, _ = signalling(FRAME, b)
    assert d_rx == b + 6 and end == b + 12               # flags overlap into 12 bits
    sched, bus, (a, r, c), log, errs = make(3)
    bus.inject_local_error(r, bit=b)
    bus.request(a, FRAME)
    sched.run_until(20_000)
    # the error frame: flags b+1..end, 8 delimiter and 3 intermission bits; then the retry
    assert errs[0][0] == "local" and errs[0][4] == (end + 12) * TPB
    assert [s for _, s, _, _ in log] == [(end + 12) * TPB]
    assert bus.tec(a) == 8 - 1                            # +8, then -1 for the retry
    assert bus.rec(r) == 1 + 8 - 1                        # its flag ended at b+6 < end: +8
    assert bus.rec(c) == 1 - 1                            # its own flag ended at end
    assert [e.kind for e in r.errors] == ["local"]
    assert [(e.kind, e.tick) for e in c.errors] == [("stuff", d_rx * TPB)]
    assert [(e.kind, e.tick) for e in a.errors] == [("bit", d_tx * TPB)]
    assert len(r.rx) == 1 and len(c.rx) == 1              # both get the retransmission


def test_a_local_error_inside_a_dominant_run_makes_a_shorter_flag():
    wire = wire_bits(FRAME.id, FRAME.data, FRAME.rtr, FRAME.dlc)
    b = next(i for i in range(30, len(wire) - 16)
             if wire[i - 2:i + 1] == [0, 0, 0] and wire[i - 3] == 1)
    d_tx, d_rx, end, _, _ = signalling(FRAME, b)
    assert d_rx == b + 3 and 6 <= end - b < 12
    sched, bus, (a, r, c), log, errs = make(3)
    bus.inject_local_error(r, bit=b)
    bus.request(a, FRAME)
    sched.run_until(20_000)
    assert errs[0][4] == (end + 12) * TPB
    assert bus.rec(r) == (1 + (8 if end > b + 6 else 0)) - 1
    assert bus.rec(c) == (1 + (8 if end > d_rx + 6 else 0)) - 1


def test_a_local_error_reaching_the_crc_delimiter_is_a_form_error_for_the_others():
    _, _, _, wire, n = signalling(FRAME, 40)
    b = n - 2                                             # two bits before the delimiter
    d_tx, d_rx, end, _, _ = signalling(FRAME, b)
    sched, bus, (a, r, c), log, errs = make(3)
    bus.inject_local_error(r, bit=b)
    bus.request(a, FRAME)
    sched.run_until(20_000)
    if d_rx == n:
        assert [e.kind for e in c.errors] == ["form"]
    assert errs[0][4] == (end + 12) * TPB


def test_a_noisy_receiver_goes_passive_and_then_stops_destroying_frames():
    """Fault confinement at work: every attempt costs the disturbed receiver 9 (its error, then
    the others' flags after its own) and the transmitter 8. After 15 attempts its REC is 135,
    error-passive; its flag is then recessive, the 16th attempt gets through to everyone else,
    and the disturbed node alone loses it."""
    wire = wire_bits(FRAME.id, FRAME.data, FRAME.rtr, FRAME.dlc)
    b = next(i for i in range(30, len(wire) - 16) if wire[i] == 1 and wire[i + 1] == 1)
    sched, bus, (a, r, c), log, errs = make(3)
    bus.disturb(r, True, bit=b)
    bus.request(a, FRAME)
    sched.run_until(200_000)
    assert len(errs) == 15 and len(log) == 1
    assert bus.error_state(r) is ErrorState.PASSIVE and bus.rec(r) == 15 * 9 + 1
    assert bus.tec(a) == 15 * 8 - 1 and bus.error_state(a) is ErrorState.ACTIVE
    assert len(c.rx) == 1 and r.rx == []
    assert bus.rec(c) == 15 - 1
    bus.disturb(r, False)
    bus.request(a, FRAME)
    sched.run_until(400_000)
    assert len(r.rx) == 1 and bus.rec(r) == 127        # a good frame: REC back to 127


def test_a_local_error_never_lands_in_the_arbitration_field():
    sched, bus, (a, r, c), log, errs = make(3)
    bus.inject_local_error(r, bit=2)
    bus.request(a, FRAME)
    sched.run_until(20_000)
    assert errs and errs[0][3] >= 14 * TPB               # flag after the RTR bit at the earliest
    assert a.lost == []


def test_bad_arguments_are_refused():
    import pytest
    sched, bus, (a, r), log, errs = make(2)
    with pytest.raises(ValueError):
        bus.inject_local_error(r, count=-1)
    with pytest.raises(ValueError):
        bus.disturb(object())


def test_a_noisy_stub_in_the_world_goes_passive_and_the_child_keeps_working():
    """``noisy:1.JOINT2@1-3``: JOINT2 sees errors on every frame it receives; the others'
    frames are destroyed until it is error-passive (15 errors), then only it loses them."""
    from hil.sim.faults import parse_fault
    from hil.sim.world import SimConfig, World
    w = World(SimConfig(robots=(0, 1), duration=4, can=True,
                        faults=(parse_fault("noisy:1.JOINT2@1-3"),)))
    w.run(int(2.9 * 16_000_000))
    bus, joint2 = w.can_buses[1], w.submodules[1]["JOINT2"]
    mcu = w.children[1].can.xcvr
    assert bus.error_frames == 15                    # then JOINT2 is passive: its flags vanish
    assert bus.error_state(joint2) is ErrorState.PASSIVE
    assert bus.error_state(mcu) is ErrorState.ACTIVE
    passive_rec = bus.rec(joint2)
    w.run()
    assert bus.error_frames == 15 and bus.rec(joint2) < passive_rec     # good frames again
    w2 = World(SimConfig(robots=(0, 1), duration=4, can=True,
                         faults=(parse_fault("noisy:1.MCU@1-3"),)))
    w2.run()
    assert w2.can_buses[1].error_frames >= 15


def test_noisy_needs_a_node_on_the_bus():
    import pytest

    from hil.sim.faults import FaultError, parse_fault
    with pytest.raises(FaultError, match="MCU"):
        parse_fault("noisy:1.ARM@1-2")
    with pytest.raises(FaultError, match="window"):
        parse_fault("noisy:1.JOINT1@1")
