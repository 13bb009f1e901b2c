"""The MAC's transition table (firmware_model/radio/mac_table.py) against the MAC itself.

Every transition the MAC makes in a set of simulated runs (a loaded ring, collisions, bursts,
deaths and recoveries, byte errors with idle noise, father failover, staggered power-on,
twins), and in a few rare paths driven on one MAC (``_rare_paths``), must be a row of the
table, and every row must be taken at least once: the table is neither wrong nor padded.
docs/mac.md must hold the diagram and table generated from it."""
from __future__ import annotations

import json
from collections import Counter
from typing import Callable

import pytest

from firmware_model.radio import mac as M
from firmware_model.radio.frame import Frame
from firmware_model.radio.integrity import seal
from firmware_model.radio.mac_table import EVENTS, STATES, TRANSITIONS, docs_section
from firmware_model.timing import CHILD_BYTE_TICKS as B
from hil.sim.faults import parse_fault
from hil.sim.world import SimConfig, World
from paths import ROOT

RUNS = [
    dict(robots=(0, 1, 2, 3, 4, 5, 6), duration=30, seed=1, load=2.0),
    dict(robots=(0, 1, 2, 3), duration=30, seed=2, load=1.0, faults=tuple(map(parse_fault, [
        "steal:2@3", "burst@6:0.3", "fail:1@8", "recover:1@12", "fail:3@14.0005"]))),
    dict(robots=(1, 2, 3, 4), duration=20, seed=3, ber=0.002, noise=True, load=1.0),
    dict(robots=(0, 1, 2), duration=20, seed=2, father_standby=True, load=1.0,
         faults=(parse_fault("fail:0@6"), parse_fault("recover:0@10"))),
    dict(robots=(1, 2, 3, 4, 5), duration=20, seed=6, power_on={3: 1.5, 1: 0.7}, ber=0.001),
    # twins of R2 powered on together: they answer together until a seeded draw parts them
    dict(robots=(1, 2, 3), duration=20, seed=1, extra=((2, 0.0, None),)),
    # the paper profile: the static ring of the whole team, robot 4 never on and 2 dying
    dict(robots=(1, 2, 3), duration=20, seed=4, load=1.0, ber=0.001,
         mac=M.MacConfig(profile="paper", team=frozenset({1, 2, 3, 4})),
         faults=(parse_fault("fail:2@6"), parse_fault("recover:2@11"))),
]


def _answer(me: int, team: set[int], poller: int, mask: int, **kw) -> tuple[M.RotationalMac, int]:
    """Robot ``me`` powers on, answers ``poller``'s invitation and sends its answer: the MAC
    (in WAIT or WINDOW) and the tick its frame ended."""
    cfg = M.MacConfig(team=frozenset(team), **kw)
    mac = M.RotationalMac(me, cfg)
    mac.power_on(0)
    poll = f"poll({me},{mask})".encode()
    t = 1000 * B
    mac.on_frame(seal(7, poller, 0, 3, poll) if cfg.checksum else Frame(7, poller, 0, 3, poll),
                 t - 20 * B, t, t)
    mac.on_timer(mac.deadline)                 # SWITCH: Ttrans after TXEN, the frame goes out
    t = mac.turn_start + cfg.ttrans + 15 * B
    mac.on_tx_done(t)
    return mac, t


def _rare_paths() -> None:
    """Paths the runs above seldom or never take, each driven on one MAC: the claim wait
    restarted by a failed frame and held off by a frame in progress (clause 28); a BOOT no
    member acknowledges, given up after the announcement limit (clause 36); a bad checksum in
    the slot before ours (clauses 43, 44) and while we hold (clause 43); frames that fail in
    an invitation's window and while a broken frame is being waited out (clause 41); a poll
    and a mask without us heard then (clauses 33, 37), and a poll while we hold."""
    mac = M.RotationalMac(1, M.MacConfig(team=frozenset({1, 2})))
    mac.power_on(0)
    mac.on_corrupt(100 * B, 2, 120 * B, 120 * B)
    mac.on_timer(mac.deadline, rx_busy=True)

    mac, t = _answer(1, {1, 2, 3}, 2, 0b1100)
    for _ in range(100):                       # 2 and 3 never acknowledge our BOOT
        if mac.mode != M.MEMBER:
            break
        if mac.phase == M.WAIT:
            t += 60 * B
            mac.on_frame(Frame(7, mac.owner, 0, 3, b""), t - 14 * B, t, t)
        else:
            mac.on_timer(mac.deadline)
            t = mac.turn_start + mac.cfg.ttrans + 15 * B
            mac.on_tx_done(t)
    assert mac.frames_sent == 2 * M.MISS_LIMIT

    mac, t = _answer(3, {1, 2, 3}, 2, 0b0110, checksum=True)
    t += 50 * B
    mac.on_frame(seal(7, 1, 0, 3, b""), t - 14 * B, t, t)            # robot 2's turn next
    t += 50 * B
    mac.on_frame(Frame(7, 2, 0, 3, b"crc(00000)"), t - 14 * B, t, t)  # its frame, bad crc
    assert mac.phase == M.HOLD
    mac.on_frame(Frame(7, 1, 0, 3, b"crc(00000)"), t, t + 14 * B, t + 14 * B)

    for me, poller, mask, length in ((1, 2, 0b0100, None), (1, 2, 0b0100, 20), (2, 1, 0b0010, 20)):
        mac, t = _answer(me, {1, 2, 3}, poller, mask)     # ring {1, 2}; the other polls 3
        t += 50 * B
        mac.on_frame(_hb(poller, t, b"poll(3,6)"), t - 23 * B, t, t)
        assert mac.phase == M.WINDOW
        end = None if length is None else t + length * B
        mac.on_corrupt(t + 5 * B, None, end, t + 8 * B)   # QUIET; HOLD (succ(3) is 1); WAIT

    # a frame breaks in o's slot before its Length (QUIET), then: a failed frame with its
    # Length, in the slot before ours or not; a bad checksum before ours; a poll; a poll
    # mask that lacks us
    for me, team, poller, mask, then in (
            (1, {1, 2, 3}, 2, 0b0100, "failed"), (1, {1, 2, 3, 4}, 2, 0b1100, "failed"),
            (1, {1, 2, 3}, 2, 0b0100, "bad crc"), (1, {1, 2, 3, 4}, 2, 0b1100, "poll(4,14)"),
            (1, {1, 2, 3, 4}, 2, 0b1100, "poll(4,12)")):
        mac, t = _answer(me, team, poller, mask, checksum=then == "bad crc")
        t += 50 * B
        mac.on_corrupt(t - 10 * B, None, None, t)
        assert mac.phase == M.QUIET
        if then == "failed":
            mac.on_corrupt(t + 5 * B, None, t + 20 * B, t + 8 * B)
        elif then == "bad crc":
            mac.on_frame(Frame(7, mac.owner, 0, 3, b"crc(00000)"), t, t + 14 * B, t + 14 * B)
        else:
            mac.on_frame(_hb(2, t, then.encode()), t, t + 24 * B, t + 24 * B)

    # a frame that polls while we hold after an uncertain closure
    mac, t = _answer(3, {1, 2, 3, 4}, 2, 0b0110, checksum=True)
    t += 50 * B
    mac.on_frame(seal(7, 1, 0, 3, b""), t - 14 * B, t, t)
    t += 50 * B
    mac.on_frame(Frame(7, 2, 0, 3, b"crc(00000)"), t - 14 * B, t, t)
    assert mac.phase == M.HOLD
    mac.on_frame(seal(7, 1, 0, 3, b"poll(4,14)"), t + 3 * B, t + 33 * B, t + 33 * B)


def _sent(mac: M.RotationalMac) -> int:
    """From SWITCH: the frame goes out; the tick its End left."""
    mac.on_timer(mac.deadline)
    t = mac.turn_start + mac.cfg.ttrans + 20 * B
    mac.on_tx_done(t)
    return t


def _window_paths() -> None:
    """Frames that end an invitation's window otherwise than clause 35 says: another robot's
    frame in a lone member's window (clause 31), a twin's second frame (clause 38), and a
    takeover by the poller's successor late enough (clause 39) that polls (clause 33) or
    whose mask lacks us (clause 37); and the cut-off (clause 40) reached on noise in QUIET."""
    mac = M.RotationalMac(2, M.MacConfig(team=frozenset({1, 2, 3})))
    mac.power_on(0)
    mac.on_timer(mac.deadline)                           # the claim
    _sent(mac)                                           # BOOT, no poll: HOLD
    mac.on_timer(mac.deadline)
    t = _sent(mac)                                       # poll(3,4): WINDOW
    assert mac.phase == M.WINDOW
    mac.on_frame(_hb(1, 0), t - 4 * B, t + 10 * B, t + 10 * B)
    assert mac.mode == M.LISTEN

    mac, t = _answer(1, {1, 2, 3}, 2, 0b0100)            # ring {1, 2}
    mac.on_frame(_hb(1, 0), t + 26 * B, t + 40 * B, t + 40 * B)   # our ID: refused
    t += 80 * B
    mac.on_frame(_hb(2, 0, b"poll(3,6)"), t - 23 * B, t, t)      # WINDOW
    mac.on_frame(_hb(1, 0), t + 26 * B, t + 40 * B, t + 40 * B)   # our ID again: a twin
    assert mac.mode == M.LISTEN

    for mask, phase in ((0b1110, M.WINDOW), (0b1100, None)):
        mac, t = _answer(1, {1, 2, 3, 4, 5}, 2, 0b1100)  # ring {1, 2, 3}
        t += 40 * B
        mac.on_frame(_hb(2, 0, b"poll(4,14)"), t - 24 * B, t, t)  # the window of 4
        poll = f"poll(5,{mask})".encode()
        mac.on_frame(_hb(3, 0, poll), t + 20 * B, t + 44 * B, t + 44 * B)
        assert (mac.phase if mac.mode == M.MEMBER else None) == phase

    mac, t = _answer(1, {1, 2, 3, 4}, 2, 0b1100)         # ring {1, 2, 3}: 3 misses cut off
    for _ in range(20):
        if mac.mode != M.MEMBER:
            break
        if mac.phase == M.WAIT:                          # noise in the owner's slot, no frame
            g = mac.turn_start + mac.cfg.ttrans + 5 * B
            mac.on_garbage(g - B, g, g)
            limit = mac.turn_start + mac.cfg.tmax
            mac.on_timer(limit, False, limit - B)
        elif mac.phase == M.SEND:
            mac.on_tx_done(mac.turn_start + mac.cfg.ttrans + 20 * B)
        else:
            mac.on_timer(mac.deadline)
    assert mac.mode == M.LISTEN


def _steal_paths() -> None:
    """Fault injection (``force_turn``, the ``steal`` fault) in every state: a member waiting
    for a turn (WAIT, WINDOW, HOLD) takes it at once; in the others there is none to take.
    And what a radio hears while ours switches or sends (a bench port is not deaf) changes
    nothing."""
    def deaf(mac: M.RotationalMac, state: str, t: int) -> None:
        mac.on_frame(_hb(2, t), t - 14 * B, t, t)
        mac.on_garbage(t + B, t + 2 * B, t + 2 * B)
        mac.on_corrupt(t + 3 * B, 2, t + 20 * B, t + 5 * B)
        assert _state(mac) == state

    def steal(mac: M.RotationalMac, state: str, now: int) -> None:
        assert _state(mac) == state
        mac.force_turn(now)
        assert _state(mac) == (state if state in ("LISTEN", "SWITCH", "SEND", "QUIET", "WATCH")
                               else "SWITCH")

    mac = M.RotationalMac(1, M.MacConfig(team=frozenset({1, 2})))
    mac.power_on(0)
    steal(mac, "LISTEN", 10 * B)
    mac.on_timer(mac.deadline)                           # the claim: SWITCH
    steal(mac, "SWITCH", mac.deadline - B)
    deaf(mac, "SWITCH", mac.deadline - 4 * B)
    mac.on_timer(mac.deadline)                           # on air: SEND
    steal(mac, "SEND", mac.turn_start + mac.cfg.ttrans + 5 * B)
    deaf(mac, "SEND", mac.turn_start + mac.cfg.ttrans + 6 * B)

    mac, t = _answer(1, {1, 2}, 2, 0b0100)               # waits for 2
    steal(mac, "WAIT", t + 10 * B)
    mac, t = _answer(1, {1, 2, 3}, 2, 0b0100)
    mac.on_frame(_hb(2, t, b"poll(3,6)"), t + 27 * B, t + 50 * B, t + 50 * B)
    steal(mac, "WINDOW", t + 60 * B)
    mac, t = _answer(1, {1, 2}, 2, 0b0100)
    mac.on_corrupt(t + 10 * B, None, None, t + 12 * B)   # broke before its Length
    steal(mac, "QUIET", t + 14 * B)
    mac.on_timer(mac.deadline)                           # quiet: our turn, R-stagger
    steal(mac, "HOLD", mac.deadline - B)

    mac = M.RotationalMac(0, M.MacConfig(team=frozenset({0, 1}), paired=True, pc=2,
                                         standby=True))
    mac.power_on(0)
    mac.on_timer(mac.deadline)                           # a standby claims: watches first
    steal(mac, "WATCH", mac.deadline - B)


def _id0_failed_paths() -> None:
    """ID 0's R-stagger is 0: on a channel with idle noise (no hold for the channel to fall
    quiet), a frame that failed after its Length in the slot before its turn leaves it nothing
    to wait: its turn at once, from WAIT, an invitation's WINDOW and QUIET (clauses 41, 44)."""
    for state in ("WAIT", "WINDOW", "QUIET"):
        mac, t = _answer(0, {0, 1, 2}, 1, 0b0010, quiet_channel=False)   # ring {0, 1}
        if state == "WINDOW":
            mac.on_frame(_hb(1, t, b"poll(2,3)"), t + 27 * B, t + 50 * B, t + 50 * B)
            t += 50 * B
        elif state == "QUIET":
            mac.on_corrupt(t + 10 * B, None, None, t + 12 * B)
            t += 12 * B
        assert _state(mac) == state
        end = t + 40 * B                                     # its promised end, now past
        mac.on_corrupt(t + 10 * B, 1 if state == "WAIT" else None, end, end + 3 * B)
        assert _state(mac) == "SWITCH", state


def _run_until_listen(mac: M.RotationalMac, limit: int = 40) -> None:
    """Nothing heard any more: the MAC takes every deadline and sends in its turns until it
    leaves the ring (the cut-off, clause 40)."""
    for _ in range(limit):
        if mac.mode != M.MEMBER:
            return
        if mac.phase == M.SEND:
            mac.on_tx_done(mac.turn_start + mac.cfg.ttrans + 20 * B)
        else:
            mac.on_timer(mac.deadline)
    raise AssertionError("never left the ring")


def _common_paths() -> None:
    """The transitions every ring makes, each driven on a bare MAC in a few calls, so that
    every row of the table is taken here in milliseconds (the simulated runs above check that
    realistic rings make no other)."""
    def expect(mac: M.RotationalMac, state: str) -> None:
        assert _state(mac) == state, (_state(mac), state)

    # LISTEN: garbage changes nothing
    mac = M.RotationalMac(1, M.MacConfig(team=frozenset({1, 2})))
    mac.power_on(0)
    mac.on_garbage(10 * B, 12 * B, 12 * B)
    expect(mac, "LISTEN")

    # the paper profile: a member of the static ring at once; cut off, then again after Tclaim
    for me, state in ((1, "SWITCH"), (2, "WAIT")):
        mac = M.RotationalMac(me, M.MacConfig(profile="paper", team=frozenset({1, 2, 3})))
        mac.power_on(0)
        expect(mac, state)
    mac.on_frame(_hb(1, 0), 100 * B, 114 * B, 114 * B)   # 1 and 3 heard: their misses count
    t = _sent(mac)
    mac.on_frame(_hb(3, 0), t + 100 * B, t + 114 * B, t + 114 * B)
    _run_until_listen(mac)
    mac.on_timer(mac.deadline)                            # silence: the static ring again
    expect(mac, "WAIT")

    # WAIT, in a ring of two {1, 2} right after our answer, waiting for 2
    mac, t = _answer(1, {1, 2}, 2, 0b0100)
    mac.on_garbage(t + B, t + 2 * B, t + 2 * B)           # within Ttrans: not 2's yet
    expect(mac, "WAIT")
    mac.on_timer(mac.deadline, True)                      # a Header is coming in: look again
    expect(mac, "WAIT")
    mac.on_frame(_hb(2, 0, b"ring(4)"), t + 100 * B, t + 121 * B, t + 121 * B)
    expect(mac, "LISTEN")                                 # left out by 2's ring view

    # HOLD: 2 missed right after our own frame (R-stagger), then what comes meanwhile
    mac, t = _answer(1, {1, 2}, 2, 0b0100)
    mac.on_timer(mac.deadline)
    expect(mac, "HOLD")
    mac.on_garbage(mac.deadline - 10 * B, mac.deadline - 9 * B, mac.deadline - 9 * B)
    expect(mac, "HOLD")
    mac.on_timer(mac.deadline, True)                      # a frame is coming in
    expect(mac, "HOLD")
    e = mac.deadline + 10 * B
    mac.on_frame(_hb(2, 0), e - 14 * B, e, e)             # 2's late frame: ours is next
    expect(mac, "SWITCH")
    mac, t = _answer(1, {1, 2}, 2, 0b0100)
    mac.on_timer(mac.deadline)
    e = mac.deadline - 2 * B
    mac.on_frame(_hb(2, 0, b"ring(4)"), e - 21 * B, e, e)   # left out while we hold
    expect(mac, "LISTEN")

    # a ring of three {1, 2, 3}: 2's frame, then 3's turn
    mac, t = _answer(1, {1, 2, 3}, 2, 0b1100)
    t += 50 * B
    mac.on_corrupt(t - 20 * B, 2, t + 20 * B, t)          # 2's frame broke after its Length
    expect(mac, "WAIT")                                   # 3's turn at its promised end
    mac, t = _answer(1, {1, 2, 3}, 2, 0b1100)
    e = t + 50 * B
    mac.on_frame(_hb(2, 0), e - 14 * B, e, e)             # 2's frame: 3's turn
    mac.on_timer(mac.deadline)                            # 3 missed: ours, certain
    expect(mac, "SWITCH")
    mac, t = _answer(1, {1, 2, 3}, 2, 0b1100)
    t += 50 * B
    mac.on_frame(_hb(2, 0), t - 14 * B, t, t)             # WAIT for 3
    mac.on_garbage(t + 10 * B, t + 12 * B, t + 12 * B)    # noise in 3's slot: QUIET
    expect(mac, "QUIET")
    mac.on_garbage(t + 14 * B, t + 15 * B, t + 15 * B)
    expect(mac, "QUIET")
    mac.on_timer(mac.deadline, False, mac.deadline - 1)   # bytes still coming: not quiet
    expect(mac, "QUIET")
    limit = t + mac.cfg.tmax
    mac.on_timer(limit, False, limit - 1)                 # noise only until E + Tmax: 3
    expect(mac, "SWITCH")                                 # missed, and ours is next
    mac, t = _answer(1, {1, 2, 3}, 2, 0b1100)
    mac.on_corrupt(t + 10 * B, None, None, t + 12 * B)    # 2's frame breaks early: QUIET
    mac.on_corrupt(t + 20 * B, None, None, t + 22 * B)    # and another
    expect(mac, "QUIET")
    mac, t = _answer(1, {1, 2, 3}, 2, 0b1100)
    mac.on_corrupt(t + 10 * B, None, None, t + 12 * B)    # 2's frame breaks early: QUIET
    e = t + 80 * B
    mac.on_frame(_hb(2, 0), e - 14 * B, e, e)             # resynchronise on 2's: WAIT for 3
    expect(mac, "WAIT")
    mac.on_corrupt(e + 10 * B, None, None, e + 12 * B)    # 3's breaks early: QUIET
    e += 80 * B
    mac.on_frame(_hb(3, 0), e - 14 * B, e, e)             # 3's frame: ours is next
    expect(mac, "SWITCH")
    mac, t = _answer(1, {1, 2, 3}, 2, 0b1100)
    _run_until_listen(mac)                                # nothing heard for a whole round

    # WINDOW: 2 invites 3 in a ring {1, 2}; succ(2) is us
    mac, t = _answer(1, {1, 2, 3}, 2, 0b0100)
    e = t + 50 * B
    mac.on_frame(_hb(2, 0, b"poll(3,6)"), e - 23 * B, e, e)
    expect(mac, "WINDOW")
    mac.on_garbage(e + 2 * B, e + 3 * B, e + 3 * B)
    expect(mac, "WINDOW")
    mac.on_timer(mac.deadline, True)
    expect(mac, "WINDOW")
    mac.on_timer(mac.deadline)                            # no answer: succ(2), ours
    expect(mac, "SWITCH")
    mac, t = _answer(1, {1, 2, 3}, 2, 0b0100)
    e = t + 50 * B
    mac.on_frame(_hb(2, 0, b"poll(3,6)"), e - 23 * B, e, e)
    a = e + mac.cfg.ttrans + 14 * B
    mac.on_frame(Frame(7, 3, 0, 5, b""), a - 14 * B, a, a)    # 3 answers: admitted; ours
    expect(mac, "SWITCH")
    # ... in a ring {1, 2, 3} where 2 invites 4: the window's end is 3's turn
    mac, t = _answer(1, {1, 2, 3, 4}, 2, 0b1100)
    e = t + 50 * B
    mac.on_frame(_hb(2, 0, b"poll(4,14)"), e - 24 * B, e, e)
    mac.on_timer(mac.deadline)
    expect(mac, "WAIT")
    mac, t = _answer(3, {1, 2, 3, 4}, 1, 0b0110)           # robot 3 in {1, 2, 3}
    e = t + 50 * B
    mac.on_frame(_hb(1, 0), e - 14 * B, e, e)             # WAIT for 2
    e += 50 * B
    mac.on_frame(_hb(2, 0, b"poll(4,14)"), e - 24 * B, e, e)
    a = e + mac.cfg.ttrans + 14 * B
    mac.on_frame(Frame(7, 4, 0, 5, b""), a - 14 * B, a, a)    # 4 answers: 1's turn next
    expect(mac, "WAIT")

    # a lone member's window: no answer, or a frame it refuses, and it pauses
    for ending in ("deadline", "outsider"):
        mac = M.RotationalMac(2, M.MacConfig(team=frozenset({1, 2, 3})))
        mac.power_on(0)
        mac.on_timer(mac.deadline)                        # the claim
        _sent(mac)                                        # BOOT: the lone pause
        mac.on_timer(mac.deadline)
        t = _sent(mac)                                    # poll(3,4): WINDOW
        expect(mac, "WINDOW")
        if ending == "deadline":
            mac.on_timer(mac.deadline)
        else:
            mac.on_frame(_hb(6, 0), t + 2 * B, t + 16 * B, t + 16 * B)   # not in the team
        expect(mac, "HOLD")

    # the father's standby PC (ID 0, PC2) in a team {0, 1, 3}
    def standby() -> M.RotationalMac:
        mac = M.RotationalMac(0, M.MacConfig(team=frozenset({0, 1, 3}), paired=True, pc=2,
                                             standby=True))
        mac.power_on(0)
        return mac

    mac = standby()
    mac.on_frame(_hb(0, 0), 86 * B, 100 * B, 100 * B)     # the active PC alone on the air
    expect(mac, "HOLD")
    mac = standby()
    mac.on_timer(mac.deadline)                            # it claims: watches first
    expect(mac, "WATCH")
    mac.on_timer(mac.deadline)                            # no Header from the active PC
    expect(mac, "SWITCH")
    mac = standby()
    mac.on_timer(mac.deadline)
    mac.on_timer(mac.deadline, True)                      # the active PC's Header comes
    expect(mac, "WAIT")
    for then in ("failed", "poll"):
        mac = standby()
        mac.on_frame(_hb(1, 0), 86 * B, 100 * B, 100 * B)
        mac.on_frame(_hb(0, 0), 126 * B, 140 * B, 140 * B)   # following 0 -> 1: WAIT for 1
        if then == "failed":
            mac.on_corrupt(150 * B, 1, 200 * B, 160 * B)  # 1's breaks: ID 0's turn, uncertain
            expect(mac, "HOLD")
            mac.on_timer(mac.deadline)                    # watched first
        else:
            mac.on_frame(_hb(1, 0, b"poll(3,3)"), 177 * B, 200 * B, 200 * B)
            expect(mac, "WINDOW")
            a = 200 * B + mac.cfg.ttrans + 14 * B
            mac.on_frame(Frame(7, 3, 0, 5, b""), a - 14 * B, a, a)   # 3 answers: ID 0's turn
        expect(mac, "WATCH")


def _hb(src: int, t: int, content: bytes = b"") -> Frame:
    return Frame(7, src, 0, 3, content)


def _father_paths() -> None:
    """The father's PCs (clause 50), driven on one MAC: a standby that hears the active PC's
    invitation from LISTEN, that claims (and watches first), that hears garbage and failed
    frames while it watches, that follows the active PC's poll from WATCH, that watches after
    a miss or an unanswered window; PC2 answering its second invitation on a check turn; PC1
    on probation refusing the other PC's frame while it watches (the slot closes)."""
    def pc2(standby: bool = True) -> M.RotationalMac:
        cfg = M.MacConfig(team=frozenset({0, 1, 2, 3}), paired=True, pc=2, standby=standby)
        mac = M.RotationalMac(0, cfg)
        mac.power_on(0)
        return mac

    def heard(mac: M.RotationalMac, src: int, t: int, content: bytes = b"") -> None:
        mac.on_frame(_hb(src, t, content), t - (14 + len(content)) * B, t, t)

    mac = pc2()
    heard(mac, 0, 100 * B, b"poll(3,7)")                 # LISTEN -> WINDOW
    mac = pc2()
    mac.on_timer(mac.deadline)                           # LISTEN -> WATCH
    mac.on_garbage(mac.deadline - 10 * B, mac.deadline - 5 * B, mac.deadline - 5 * B)

    def follower() -> tuple[M.RotationalMac, int]:       # a standby in a ring {0, 1}
        mac = pc2()
        heard(mac, 1, 100 * B)
        heard(mac, 0, 140 * B)                           # LISTEN -> WAIT for robot 1
        return mac, 140 * B

    mac, t = follower()
    mac.force_turn(t + 10 * B)                           # the steal fault: WAIT -> WATCH
    assert mac.phase == M.WATCH
    mac = M.RotationalMac(0, M.MacConfig(team=frozenset({0, 1, 2, 3}), paired=True, pc=2,
                                         standby=True, quiet_channel=False))
    mac.power_on(0)                                      # idle noise: no hold for quiet
    heard(mac, 1, 100 * B)
    heard(mac, 0, 140 * B)                               # a standby following 0 -> 1
    mac.on_corrupt(150 * B, None, None, 152 * B)         # 1's frame breaks: WAIT -> QUIET
    mac.on_timer(mac.deadline)                           # quiet: ID 0's turn, watched first
    assert mac.phase == M.WATCH
    mac, t = follower()
    mac.on_timer(mac.deadline)                           # 1 missed: WAIT -> WATCH
    mac.on_corrupt(mac.turn_start + 8 * B, None, None, mac.turn_start + 10 * B)   # QUIET
    mac, t = follower()
    heard(mac, 1, t + 40 * B)                            # WAIT -> WATCH
    mac.on_corrupt(t + 45 * B, None, t + 60 * B, t + 48 * B)                      # WAIT
    mac, t = follower()
    heard(mac, 1, t + 40 * B)
    heard(mac, 0, t + 70 * B, b"poll(3,3)")              # WATCH -> WINDOW
    mac, t = follower()
    heard(mac, 1, t + 40 * B, b"poll(3,3)")              # WAIT -> WINDOW
    mac.on_timer(mac.deadline)                           # no answer: WINDOW -> WATCH
    mac = pc2(standby=False)
    for i in range(2):                                   # the first invitation passes
        heard(mac, 1, (100 + 100 * i) * B, b"poll(0,2)")  # LISTEN -> WATCH
    assert mac.phase == M.WATCH

    # PC1, which missed a turn with nothing heard: it checks (clause 50), watches its turn,
    # and the other PC's frame heard then stands it by
    mac = M.RotationalMac(0, M.MacConfig(team=frozenset({0, 1, 2}), paired=True, pc=1))
    mac.power_on(0)
    heard(mac, 1, 100 * B, b"poll(0,2)")                 # invited: ring {0, 1}
    _sent(mac)
    mac.on_timer(mac.deadline)                           # robot 1 missed: our turn, R-stagger
    heard(mac, 0, mac.turn_start + 40 * B)               # the other PC: probation; WAIT for 1
    heard(mac, 1, mac.turn_start + 80 * B)               # our turn, watched
    assert mac.phase == M.WATCH
    mac.on_timer(mac.deadline, rx_busy=True)             # a frame coming: read its Source
    assert mac.phase == M.WATCH
    heard(mac, 1, mac.turn_start + 30 * B)               # robot 1's: our turn, watched again
    assert mac.phase == M.WATCH and not mac.standby
    heard(mac, 0, mac.turn_start + 30 * B)               # the other PC's: stand by, -> WAIT
    assert (mac.phase, mac.owner) == (M.WAIT, 1) and mac.standby   # it checked (clause 50)

    # PC1 alone in its ring (it claimed, its radio deaf), bytes heard long after its frame:
    # it checks its next turn, and the other PC's frame there stands it by, alone: -> HOLD
    mac = M.RotationalMac(0, M.MacConfig(team=frozenset({0, 1, 2}), paired=True, pc=1))
    mac.power_on(0)
    mac.on_timer(mac.deadline)                           # LISTEN: claims -> SWITCH
    t = _sent(mac)                                       # -> HOLD, a lone member's pause
    mac.on_garbage(t + 600 * B, t + 610 * B, t + 610 * B)   # long after our frame: check
    assert mac._deaf_check
    mac.on_timer(mac.deadline)                           # our turn, watched
    assert mac.phase == M.WATCH
    heard(mac, 0, mac.turn_start + 30 * B)               # the other PC's frame: -> HOLD
    assert mac.phase == M.HOLD and mac.standby and mac.ring == (0,)


HOOKS = {"on_frame": "frame", "on_corrupt": "failed frame", "on_garbage": "garbage",
         "on_timer": "deadline", "on_tx_done": "tx done", "power_on": "power on",
         "force_turn": "steal"}


def _state(mac) -> str:
    return "LISTEN" if mac.mode == M.LISTEN else mac.phase.upper()


def _recorded(run: Callable[[], None]) -> Counter:
    """The transitions the MAC makes while ``run()`` runs, counted."""
    seen: Counter = Counter()
    mp = pytest.MonkeyPatch()

    def hook(name, event):
        orig = getattr(M.RotationalMac, name)

        def recorded(self, *a, **k):
            before = _state(self)
            out = orig(self, *a, **k)
            seen[(before, event, _state(self))] += 1
            return out
        mp.setattr(M.RotationalMac, name, recorded)
    for name, event in HOOKS.items():
        hook(name, event)
    try:
        run()
    finally:
        mp.undo()
    return seen


def _stall_paths() -> None:
    """A bench station resynchronised after a stall watches its first turn (clause 5): the
    next robot's frame in it, or its Header coming when the watch ends, means the ring left it
    out meanwhile."""
    for busy in (False, True):
        mac, t = _answer(2, {1, 2, 3}, 1, 0b1010)
        late = t + 10 * 16_000_000
        mac.resync(late)
        t = late + 100 * B
        mac.on_frame(Frame(7, 1, 0, 3, b""), t - 14 * B, t, t)
        if busy:
            mac.on_timer(mac.deadline, rx_busy=True)
        else:
            t += 20 * B
            mac.on_frame(Frame(7, 3, 0, 3, b""), t - 14 * B, t, t)


def _bare_drives() -> None:
    _rare_paths()
    _stall_paths()
    _father_paths()
    _window_paths()
    _steal_paths()
    _id0_failed_paths()
    _common_paths()


@pytest.fixture(scope="module")
def driven() -> Counter:
    """Every transition of the drives on bare MACs: a few milliseconds."""
    return _recorded(_bare_drives)


@pytest.fixture(scope="module")
def observed() -> Counter:
    """Every transition of the simulated rings (seconds)."""
    def runs() -> None:
        for kw in RUNS:
            World(SimConfig(**kw)).run()
    return _recorded(runs)


def test_every_transition_the_mac_makes_is_in_the_table(observed, driven):
    rows = {(t.state, t.event, t.next) for t in TRANSITIONS}
    missing = sorted((set(observed) | set(driven)) - rows)
    assert not missing, f"transitions the table does not list: {missing}"


@pytest.mark.parametrize("row", TRANSITIONS, ids=lambda t: f"{t.state}-{t.event}-{t.next}")
def test_each_row_is_taken_on_a_bare_mac(driven, row):
    """Table-driven: each row of the table is a transition some drive makes on a bare MAC
    (no world, no scheduler), all of them in a few milliseconds."""
    assert (row.state, row.event, row.next) in driven, \
        f"no drive takes {row} (wrong, or a drive is missing)"


EVERY_RING = {
    ("LISTEN", "power on", "LISTEN"), ("LISTEN", "deadline", "SWITCH"),
    ("LISTEN", "frame", "SWITCH"), ("WAIT", "frame", "WAIT"), ("WAIT", "frame", "SWITCH"),
    ("WAIT", "frame", "WINDOW"), ("WAIT", "deadline", "SWITCH"), ("WINDOW", "frame", "WAIT"),
    ("WINDOW", "deadline", "WAIT"), ("SWITCH", "deadline", "SEND"),
    ("SEND", "tx done", "WAIT"), ("SEND", "tx done", "WINDOW"), ("SEND", "tx done", "HOLD"),
    ("HOLD", "deadline", "SWITCH"), ("QUIET", "deadline", "WAIT"),
    ("LISTEN", "power on", "WAIT"),           # (the paper profile's run)
}
"""Rows of the start-up, the rotation, invitations, misses and failed frames."""


def test_the_simulated_rings_take_the_rows_every_ring_takes(observed):
    """The realistic runs are not vacuous: the rows every ring takes are among theirs (59 of
    the 101 rows in all)."""
    assert EVERY_RING <= set(observed), sorted(EVERY_RING - set(observed))


def test_the_table_names_only_known_states_and_events():
    assert {t.state for t in TRANSITIONS} | {t.next for t in TRANSITIONS} <= set(STATES)
    assert {t.event for t in TRANSITIONS} <= set(EVENTS)
    assert set(M.DEADLINE_HANDLERS) | {M.SEND} == {s.lower() for s in STATES} - {"listen"}


def test_the_phases_are_an_enum_whose_members_are_the_old_strings():
    """``mac_phases.Phase``: one member per MEMBER state of the table, each equal to the string
    it was before (same hash, same text in an f-string or JSON), so traces and tables keep it."""
    assert {p.value for p in M.Phase} == {s.lower() for s in STATES} - {"listen"}
    for p in M.Phase:
        assert p == p.value and hash(p) == hash(p.value) and {p.value: 1}[p] == 1
        assert str(p) == f"{p}" == p.value and json.dumps(p) == f'"{p.value}"'
    mac = M.RotationalMac(1)
    mac.power_on(0)
    assert isinstance(mac.phase, M.Phase)

def test_docs_hold_the_generated_diagram_and_table():
    text = (ROOT / "docs" / "mac.md").read_text()
    begin, end = "<!-- mac-table:begin -->\n", "<!-- mac-table:end -->"
    assert begin in text and end in text, "docs/mac.md lacks the mac-table markers"
    held = text.split(begin, 1)[1].split(end, 1)[0]
    assert held == docs_section(), \
        "docs/mac.md is stale: python -m firmware_model.radio.mac_table prints the section"
