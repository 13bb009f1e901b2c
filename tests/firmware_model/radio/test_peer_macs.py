"""Peer MACs (firmware_model/radio/peer_macs.py, docs/peer-macs.md): pure ALOHA, slotted ALOHA
and non-persistent CSMA in place of the rotational MAC, driven by the unchanged RadioStation in
the simulated world; delivery accounting, determinism, and throughput against the textbook
curves (the harness is benchmarks/peer_macs.py)."""
from __future__ import annotations

import importlib.util
import math

import pytest

from firmware_model.radio.content import cmd
from firmware_model.radio.frame import BROADCAST, Frame, FrameType
from firmware_model.radio.mac import (
    Deliver, Duplicate, MacConfig, Outcome, RotationalMac, SubmitError, Transmit, TxEnable,
)
from firmware_model.radio.peer_macs import (
    AlohaMac, CsmaMac, PeerConfig, SlottedAlohaMac, default_slot, install, make_mac,
)
from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS, TTRANS_TICKS
from hil.sim.world import SimConfig, World
from paths import ROOT

PEERS = ("aloha", "slotted", "csma")
BT = CHILD_BYTE_TICKS
TT = TTRANS_TICKS

_spec = importlib.util.spec_from_file_location(
    "peer_macs_bench", ROOT / "benchmarks" / "peer_macs.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


def _world(kind, robots=(0, 1, 2), seed=4, load=1.0, load_until=16.0, duration=24.0, **kw):
    """A world with the usual random load, its stations switched to ``kind``."""
    w = World(SimConfig(robots=robots, duration=duration, seed=seed, load=load,
                        load_until=load_until, keep_records=True, **kw))
    install(w, kind)
    return w


def _actions(out, t):
    return [a for a in out if type(a) is t]


# -- the sans-IO machine -------------------------------------------------------------------


def _fire(mac, now, **kw):
    """Run the MAC's timer at its deadline (as the station does)."""
    assert mac.deadline is not None and mac.deadline <= now
    return mac.on_timer(now, **kw)


def test_make_mac_kinds():
    assert isinstance(make_mac("rotational", 1), RotationalMac)
    assert isinstance(make_mac("aloha", 1), AlohaMac)
    assert isinstance(make_mac("slotted", 1), SlottedAlohaMac)
    assert isinstance(make_mac("csma", 1), CsmaMac)
    with pytest.raises(ValueError, match="unknown MAC"):
        make_mac("tdma", 1)


def test_aloha_sends_at_once_retries_with_backoff_then_fails_with_reason():
    mac = AlohaMac(1, MacConfig(team=frozenset({1, 2})), seed=0)
    assert _actions(mac.power_on(0), TxEnable) == [TxEnable(False)]
    assert mac.deadline is None                      # nothing to say: no heartbeat
    m = mac.submit(2, [cmd("movex", 10)], 1000)
    assert mac.deadline == 1000
    assert mac.on_timer(1000) == [TxEnable(True)]
    assert mac.deadline == 1000 + TT
    starts = []
    now = 1000 + TT
    for attempt in range(1, 5):
        out = _fire(mac, now)
        (tx,) = _actions(out, Transmit)
        starts.append(now)
        assert tx.frame.dst == 2 and tx.frame.num == m.num and m.attempts == attempt
        end = now + len(tx.data) * BT
        assert mac.on_tx_done(end) == [TxEnable(False)]
        now = mac.deadline                           # the ack wait ends
        assert now == end + TT + mac.frame_ticks + 2 * PC_BYTE_TICKS + 64
        out = _fire(mac, now)
        if attempt == 4:
            (o,) = _actions(out, Outcome)
            assert not o.delivered and o.reason == "no acknowledgement from 2 after 4 attempts"
            assert mac.pending == 0 and mac.deadline is None
            break
        assert out == [] and now <= mac.deadline <= now + 8 * mac.frame_ticks
        now = mac.deadline
        assert _fire(mac, now) == [TxEnable(True)]
        now += TT
    assert len(set(b - a for a, b in zip(starts, starts[1:]))) == 3   # random backoffs


def test_receiver_delivers_once_acks_at_once_and_reacks_duplicates():
    rx = AlohaMac(2, MacConfig(team=frozenset({1, 2})), seed=0)
    rx.power_on(0)
    f = Frame(dst=2, src=1, num=7, type=FrameType.INSTRUCTION, content=b"movex(10)")
    out = rx.on_frame(f, 10_000, 500_000, 500_000)
    assert out == [Deliver(1, 2, 7, 2, (cmd("movex", 10),))]
    assert rx.deadline == 500_000                    # the ack goes as soon as possible
    assert rx.on_timer(500_000) == [TxEnable(True)]
    (tx,) = _actions(_fire(rx, 500_000 + TT), Transmit)
    assert tx.frame.content == b"ack(1,7)" and tx.frame.dst == 1
    assert tx.frame.type == FrameType.BROADCAST_INFO and len(tx.data) == 22
    rx.on_tx_done(2_000_000)
    out = rx.on_frame(f, 3_000_000, 3_500_000, 3_500_000)     # the sender retransmits
    assert out == [Duplicate(1, 7)] and rx.deadline == 3_500_000


def test_ack_ends_the_message_and_a_late_ack_is_harmless():
    mac = AlohaMac(1, MacConfig(team=frozenset({1, 2})), seed=0)
    mac.power_on(0)
    m = mac.submit(2, [cmd("movex", 1)], 0)
    mac.on_timer(0)
    mac.on_timer(TT)
    mac.on_tx_done(TT + 23 * BT)
    ack = Frame(dst=1, src=2, num=0, type=3, content=f"ack(1,{m.num})".encode())
    (o,) = mac.on_frame(ack, 0, 1_000_000, 1_000_000)
    assert o == Outcome(m, True, "") and m.state == "delivered" and mac.pending == 0
    assert mac.on_frame(ack, 0, 1_200_000, 1_200_000) == []


def test_slotted_frames_start_on_shared_slot_boundaries():
    cfg = MacConfig(team=frozenset({1, 2}))
    mac = SlottedAlohaMac(1, cfg, PeerConfig(frame_bytes=40), seed=0)
    slot = mac.slot
    assert slot == default_slot(40, TT) == 40 * PC_BYTE_TICKS + TT + 64
    mac.power_on(0)
    mac.submit(2, [cmd("movex", 1)], 5 * slot + 123)
    assert mac.deadline == 6 * slot - TT                 # TXEN Ttrans before the boundary
    mac = SlottedAlohaMac(1, cfg, PeerConfig(frame_bytes=40), seed=0)
    mac.power_on(0)
    mac.submit(2, [cmd("movex", 1)], 6 * slot - TT + 1)
    assert mac.deadline == 7 * slot - TT                 # too late to switch for 6 x slot
    assert mac.on_timer(7 * slot - TT) == [TxEnable(True)]
    (tx,) = _actions(_fire(mac, 7 * slot), Transmit)
    with pytest.raises(SubmitError, match="one slot"):
        mac.submit(2, [cmd("movex", 123456789)] * 2, 0)   # a 46-byte frame: no slot fits it


@pytest.mark.parametrize("late", [1, 307, 40_000])
def test_a_slotted_timer_handler_that_comes_late_still_sends_in_its_slot(late):
    """The MB90F549 model takes a timer interrupt about 300 ticks after it is due: the
    slotted MAC, allowing 64, took every try for the next slot, re-armed, was as late again,
    and on the CPU model (the command line's default) never sent a frame. A handler up to
    2.5 ms late sends in the slot it was armed for; later than that, in the next one."""
    cfg = MacConfig(team=frozenset({1, 2}))
    mac = SlottedAlohaMac(1, cfg, PeerConfig(frame_bytes=40), seed=0)
    slot = mac.slot
    mac.power_on(0)
    mac.submit(2, [cmd("movex", 1)], 5 * slot + 123)
    assert mac.deadline == 6 * slot - TT
    now = 6 * slot - TT + late
    assert mac.on_timer(now) == [TxEnable(True)]
    (tx,) = _actions(_fire(mac, now + TT), Transmit)          # Ttrans after TXEN
    assert tx.frame.dst == 2
    mac = SlottedAlohaMac(1, cfg, PeerConfig(frame_bytes=40), seed=0)
    mac.power_on(0)
    mac.submit(2, [cmd("movex", 1)], 5 * slot + 123)
    assert mac.on_timer(6 * slot - TT + 40_001) == []         # too late: the next slot
    assert mac.deadline == 7 * slot - TT


def test_slotted_aloha_delivers_on_the_cpu_model():
    """``rprs sim --mac slotted`` on the CPU model: 0 occupations, every message pending."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    w = _world("slotted", cpu=DEFAULT_COSTS)
    w.run()
    s = w.summary()
    assert s["delivered"] > 0 and w.air.occupations > 10, (s["delivered"], w.air.occupations)


@pytest.mark.parametrize("kind,checksum", [("slotted", False), ("slotted", True),
                                           ("aloha", True)])
def test_a_saturated_peer_ring_sends_messages_its_mac_takes(kind, checksum):
    """``--load saturate`` made every message the rotational MAC's largest: a slotted frame
    must fit its slot, and with the checksum an ALOHA frame its crc, so every one was
    refused at submit and the run reported an idle channel (submitted 0, exit 0). The load
    fills a message to what the MAC takes."""
    w = _world(kind, load="saturate", load_until=None, duration=6.0,
               mac=MacConfig(checksum=checksum))
    w.run()
    s = w.summary()
    assert s["submitted"] > 5 and w.air.occupations > 5, (s["submitted"], w.air.occupations)
    assert sum(v["refused"] for v in s["robots"].values()) == 0


def test_the_summary_says_how_many_messages_a_mac_refused(capsys):
    """``rprs sim --mac slotted --frame-bytes 23 --load 1``: most of the load's messages do
    not fit a 23-byte frame; the run said nothing of them."""
    from hil.cli import main
    assert main(["sim", "--mac", "slotted", "--frame-bytes", "23", "--load", "1", "--cpu",
                 "ideal", "--duration", "3", "--no-progress"]) == 0
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if ln.startswith("messages refused at submit: "))
    assert int(line.split()[4]) > 0


def test_csma_senses_bytes_and_defers_at_random():
    mac = CsmaMac(1, MacConfig(team=frozenset({1, 2})), seed=0)
    mac.power_on(0)
    mac.submit(2, [cmd("movex", 1)], 100_000)
    assert mac.on_timer(100_000, False, 100_000 - BT) == []     # a byte one byte time ago
    assert mac.sense_busy == 1
    t = mac.deadline
    assert 100_000 < t <= 100_000 + 2 * mac.frame_ticks
    assert mac.on_timer(t, True, t - 10) == []                   # a frame in progress
    t = mac.deadline
    assert mac.on_timer(t, False, t - 2 * PC_BYTE_TICKS) == [TxEnable(True)]  # 2 quiet bytes
    assert mac.sense_attempts == 3


def test_csma_ack_guard_after_a_frame_for_another_robot():
    mac = CsmaMac(1, MacConfig(team=frozenset({1, 2, 3})), seed=0)
    mac.power_on(0)
    f = Frame(dst=3, src=2, num=0, type=2, content=b"movex(1)")
    mac.on_frame(f, 0, 1_000_000, 1_000_000)
    mac.submit(3, [cmd("movex", 1)], 1_000_000)
    quiet = 1_000_000 + 2 * PC_BYTE_TICKS
    assert mac.on_timer(quiet, False, 1_000_000) == []          # the ack of robot 3 may come
    assert mac.sense_busy == 1
    assert mac.busy(1_000_000 + TT + 2 * PC_BYTE_TICKS - 1, False, 1_000_000)
    assert not mac.busy(1_000_000 + TT + 2 * PC_BYTE_TICKS, False, 1_000_000)


def test_csma_sender_waits_for_its_own_ack_before_sensing_idle():
    mac = CsmaMac(1, MacConfig(team=frozenset({1, 2})), seed=0)
    mac.power_on(0)
    mac.submit(2, [cmd("movex", 1)], 0)
    mac.submit(2, [cmd("movex", 2)], 0)
    assert mac.on_timer(0, False, None) == [TxEnable(True)]
    (tx,) = _actions(mac.on_timer(TT, False, None), Transmit)
    end = TT + len(tx.data) * BT
    mac.on_tx_done(end)
    # Deaf until end + Ttrans (no observation, not counted), then the ack guard: busy.
    assert mac.on_timer(end, False, None) == [] and mac.sense_attempts == 1
    assert mac.sense_busy == 0 and end < mac.deadline
    assert mac.busy(end + TT, False, None)                       # hearing, but the ack is due
    assert not mac.busy(end + TT + 2 * PC_BYTE_TICKS, False, None)

# -- end to end in the simulated world -------------------------------------------------------


@pytest.mark.parametrize("kind", PEERS)
def test_end_to_end_between_three_robots_accounting(kind):
    w = _world(kind)
    w.run()
    s = w.summary()
    assert s["submitted"] >= 40
    assert s["pending"] == 0
    assert s["submitted"] == s["delivered"] + s["failed"]
    assert s["delivered"] >= 0.8 * s["submitted"]
    assert s["duplicate_deliveries"] == 0 and s["corrupt_deliveries"] == 0
    for o in w.outcomes:
        assert o.delivered or o.reason
    # Every delivery was intact, counted once per receiver; broadcasts reach both others.
    assert sum(w.deliveries.values()) == len(w.deliveries)
    bcast = [m for m in w.messages if m.dst == BROADCAST and m.state == "delivered"]
    assert bcast and all(sum(1 for k in w.deliveries if k[0] == m.src and k[1] == m.num
                             and w.messages[k[2] - 1] is m) == 2 for m in bcast)
    for st in w.stations.values():
        assert st.mac.mode == "member" and set(st.mac.ring) == {0, 1, 2}


@pytest.mark.parametrize("kind", PEERS)
def test_same_seed_same_trace_other_seed_differs(kind):
    def run(seed):
        evs = []
        w = World(SimConfig(robots=(1, 2, 3), duration=5.0, seed=seed, load=4.0),
                  on_event=evs.append)
        install(w, kind)
        w.run()
        return evs
    a, b = run(5), run(5)
    assert a == b and len(a) > 200
    assert run(6) != a


def test_peer_macs_contend_the_rotational_mac_does_not():
    """Same seeded load: contention MACs collide, CSMA far less than ALOHA."""
    coll = {}
    for kind in ("aloha", "csma"):
        r = bench.measure(kind, 0.2, robots=(0, 1, 2, 3, 4, 5, 6), duration=12.0, seed=2)
        coll[kind] = r["collided"]
    r = bench.measure("rotational", 0.2, robots=(1, 2, 3), duration=16.0, warmup=10.0, seed=2)
    assert r["collided"] == 0 and r["delivered"] > 0
    assert coll["csma"] < 0.5 * coll["aloha"]


def test_csma_with_idle_noise_senses_frames_only():
    """With the PTR2000's idle noise, byte sensing always hears 'busy'; frame sensing works."""
    for sense, ok in (("bytes", False), ("frame", True)):
        w = World(SimConfig(robots=(1, 2), duration=4.0, seed=1, noise=True))
        install(w, "csma", PeerConfig(sense=sense))
        w.sched.at(100_000, lambda w=w: w.submit(1, 2, [cmd("movex", 3)]))
        w.run()
        assert (w.stats[1].delivered == 1) is ok


# -- throughput against the curves ---------------------------------------------------------


def test_slotted_aloha_near_g_1_throughput_is_1_over_e():
    r = bench.measure("slotted", 0.2, duration=32.0, seed=1)
    assert 0.8 <= r["G"] <= 1.2
    assert r["tx"] >= 500
    assert abs(r["S"] - math.exp(-1)) <= 0.05
    assert abs(r["S"] - bench.analytic("slotted", r["G"])) <= 0.05


def test_pure_aloha_near_g_half_throughput_is_18_percent():
    r = bench.measure("aloha", 0.15, duration=32.0, seed=1)
    assert 0.35 <= r["G"] <= 0.65 and r["tx"] >= 400
    assert abs(r["S"] - 0.184) <= 0.05
    assert abs(r["S"] - bench.analytic("aloha", r["G"], n=7)) <= 0.03


@pytest.mark.parametrize("lam", [0.1, 0.2, 0.3])
def test_csma_follows_kleinrock_tobagi_with_its_ack_exchange(lam):
    r = bench.measure("csma", lam, duration=32.0, seed=1)
    assert abs(r["S"] - bench.csma_with_acks(r["G_kt"])) <= 0.05
    # The textbook curve counts data frames only: the acks' air time lifts S above it.
    assert bench.analytic("csma", r["G_kt"]) < r["S"] <= bench.analytic("csma", r["G_kt"]) + 0.1
    assert r["collided"] < 0.2


def test_low_load_throughput_equals_offered_load():
    """Below capacity every data frame and its ack get through: S ~ G for every peer."""
    for kind in PEERS:
        r = bench.measure(kind, 0.03, duration=32.0, seed=3)
        assert r["S"] == pytest.approx(r["G"], abs=0.02)


def test_frames_from_outside_the_team_are_never_acted_on():
    mac = AlohaMac(1, MacConfig(team=frozenset({1, 2})), seed=0)
    mac.power_on(0)
    f = Frame(dst=1, src=5, num=3, type=2, content=b"movex(1)")
    out = mac.on_frame(f, 0, 100_000, 100_000)
    assert not _actions(out, Deliver) and mac.deadline is None and 5 not in mac.ring
