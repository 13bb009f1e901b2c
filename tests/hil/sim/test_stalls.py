"""A station woken far past its deadlines does not transmit on a stale view, and a station
that restarted is never taken for its former self: the real-time scheduler's stall watch,
the station's and the MAC's resynchronisation, and the start of a bench station
(docs/guarantees.md, "Stalls and restarts at the bench")."""
from __future__ import annotations

import threading
import time

from firmware_model.radio.frame import Frame
from firmware_model.radio.mac import (
    LISTEN, MEMBER, SEND, WAIT, WATCH, MacConfig, Miss, ModeChange, Refused, RotationalMac,
    Transmit, TxEnable,
)
from firmware_model.station import Stalled, build_station
from firmware_model.timing import TICK_HZ
from hil.bench.runner import REALTIME_MARGINS, realtime_config, stall_threshold
from hil.sim.realtime import RealTimeScheduler

MS = TICK_HZ // 1000


# -- the scheduler ---------------------------------------------------------------------------

def test_an_event_run_after_a_stall_sees_the_time_it_runs_at_and_the_stall_is_told_first():
    """The scheduler's thread is held 1 s (a handler blocked; SIGSTOP holds every thread the
    same way) with a 200 ms threshold: the stall is handled before the overdue events, which
    then see the tick they run at, not their stale ones. (Due in the same pass as the blocked
    handler or in the next, and a busy machine may add stalls of its own before.)"""
    s = RealTimeScheduler()
    seen: list[tuple[str, int, int]] = []
    s.watch_stalls(200 * MS, lambda late, now: seen.append(("stall", late, now)))
    s.at(10 * MS, lambda: time.sleep(1.0))
    s.at(10 * MS, lambda: seen.append(("event", 10 * MS, s.now)))     # the same pass
    s.at(30 * MS, lambda: seen.append(("event", 30 * MS, s.now)))
    s.run_for(1.3)
    big = [i for i, (k, late, _) in enumerate(seen) if k == "stall" and late > 800 * MS]
    assert len(big) == 1, seen
    _, late, at = seen[big[0]]
    assert at > 1000 * MS
    events = [(i, now) for i, (k, _, now) in enumerate(seen) if k == "event"]
    assert len(events) == 2 and all(i > big[0] and now >= at for i, now in events), seen
    assert [late for _, late in s.stalls] == [late for k, late, _ in seen if k == "stall"]


def test_without_a_stall_watch_an_overdue_event_keeps_its_own_tick():
    """The simulator's real-time mode and the radio hub do not watch: unchanged."""
    s = RealTimeScheduler()
    seen: list[int] = []
    s.at(10 * MS, lambda: time.sleep(0.2))
    s.at(20 * MS, lambda: seen.append(s.now))
    s.run_for(0.3)
    assert seen == [20 * MS] and s.stalls == []


def test_a_late_wake_within_the_threshold_is_no_stall():
    s = RealTimeScheduler()
    calls: list[int] = []
    s.watch_stalls(2 * TICK_HZ, lambda late, now: calls.append(late))
    s.at(10 * MS, lambda: time.sleep(0.3))
    s.at(20 * MS, lambda: None)
    s.run_for(0.5)
    assert calls == []


def test_a_timer_run_more_than_20_ms_late_is_noted_and_told_short_of_a_stall():
    """Lateness the margins absorb but a bench run must know of (``lates``, ``watch_late``):
    a timer held 150 ms by a blocked handler is noted with its due tick; one 1 ms late is not;
    with a stall watch, the events a stall made overdue are the stall's, not noted again."""
    s = RealTimeScheduler()
    told: list[tuple[int, int]] = []
    s.watch_late(lambda late, due: told.append((due, late)))
    s.at(10 * MS, lambda: time.sleep(0.15))
    s.at(20 * MS, lambda: None)
    s.at(400 * MS, lambda: None)
    s.run_for(0.5)
    assert [due for due, _ in told] == [20 * MS], told
    assert 130 * MS < told[0][1] < 400 * MS and list(s.lates) == told

    stalled = RealTimeScheduler()
    noted: list[int] = []
    stalled.watch_stalls(100 * MS, lambda late, now: None)
    stalled.watch_late(lambda late, due: noted.append(due))
    stalled.at(10 * MS, lambda: time.sleep(0.3))
    stalled.at(20 * MS, lambda: None)
    stalled.run_for(0.5)
    assert stalled.stalls and noted == [] and not stalled.lates


def test_a_bench_child_tells_a_late_timer_as_an_event():
    """``rprs child --events`` writes ``{"ev": "late", "robot": 3, "late": ticks}`` for a
    timer run late short of a stall (docs/bench.md, "Stalls and restarts")."""
    import io
    import json
    from hil.bench.runner import Late, _events_printer
    out = io.StringIO()
    observe = _events_printer(out, 3)
    observe(None, Late(25 * MS), 1234)
    assert json.loads(out.getvalue()) == {"t": 1234, "ev": "late", "robot": 3, "late": 25 * MS}


def test_on_start_runs_before_anything_posted_earlier():
    s = RealTimeScheduler()
    order: list[str] = []
    s.post(order.append, "posted")
    s.on_start(lambda: order.append("start"))
    s.post(s.stop)
    s.run_for(1.0)
    assert order == ["start", "posted"]


def test_an_input_that_came_before_a_timer_runs_before_it_though_taken_in_late():
    """The scheduler's thread is held 300 ms (a busy host gives the process no CPU); meanwhile
    an input arrives (at 5 ms) before a timer due at 20 ms. Taken in late, it still runs first,
    as an MCU takes the receive interrupt before the timer: a supervision timer must not judge
    "nothing came" when only the process was late (before: the due timer ran first)."""
    s = RealTimeScheduler()
    order: list[str] = []
    held = threading.Event()

    def hold() -> None:
        held.set()
        time.sleep(0.3)
    s.at(1 * MS, hold)
    s.at(20 * MS, order.append, "timer")
    poster = threading.Thread(target=lambda: (held.wait(2.0),
                                              s.post_at(5 * MS, order.append, "input")))
    poster.start()
    s.run_for(0.4)
    poster.join()
    assert order == ["input", "timer"]


def test_an_input_posted_late_runs_after_the_timers_due_before_it():
    """The other way round: an input that arrived after a timer's tick runs after it, and
    ``now`` never goes back (the input runs at the tick it was posted at, the timer at its
    own or later)."""
    s = RealTimeScheduler()
    seen: list[tuple[str, int]] = []
    s.at(10 * MS, lambda: time.sleep(0.05))
    s.at(20 * MS, lambda: seen.append(("timer", s.now)))
    s.at(15 * MS, lambda: s.post_at(40 * MS, lambda: seen.append(("input", s.now))))
    s.run_for(0.1)
    assert [k for k, _ in seen] == ["timer", "input"]
    assert seen[0][1] <= seen[1][1]


def test_a_can_frame_read_late_is_posted_at_its_bus_timestamp():
    """The python-can bridge posts a received frame at the tick of its bus timestamp (a wall
    clock time of the last second: SocketCAN's kernel stamp), so a frame that waited while
    the process got no CPU runs before the timers due after it came (the scheduler's order is
    the test above); a stamp from another clock (an adapter's own) is not trusted."""
    import can
    from can_bus.bridge import PythonCanBus
    from can_bus.frames import CanFrame

    class Sched(RealTimeScheduler):
        __slots__ = ("posted",)

        def post_at(self, tick, fn, *args):
            self.posted.append((tick, self.wall()))
    chan = f"late-frame-{id(object())}"
    s = Sched()
    s.posted = []
    bus = PythonCanBus(s, can.Bus(interface="virtual", channel=chan))
    other = can.Bus(interface="virtual", channel=chan, preserve_timestamps=True)
    try:
        other.send(CanFrame(0x123, b"\x01").to_message(timestamp=time.time() - 0.2))
        other.send(CanFrame(0x124, b"\x01").to_message(timestamp=12.5))   # its own clock
        deadline = time.monotonic() + 5.0
        while len(s.posted) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        bus.close()
        other.shutdown()
    (tick, wall), (tick2, wall2) = s.posted
    assert 190 * MS <= wall - tick <= 400 * MS, (wall - tick) / MS
    assert 0 <= wall2 - tick2 < MS        # taken as arriving when read


def test_the_bench_stall_threshold_is_tslot_of_the_margin_set():
    assert stall_threshold(realtime_config()) == REALTIME_MARGINS["tslot"] == 80 * MS
    assert stall_threshold(MacConfig()) == MacConfig().tslot


# -- the MAC ---------------------------------------------------------------------------------

TEAM = frozenset({1, 2, 3})


def member_2(tx_end: int = 2_000_000) -> RotationalMac:
    """R2 invited by R1 into ring {1, 2, 3}; its answer sent; waiting for R3's turn."""
    mac = RotationalMac(2, MacConfig(team=TEAM))
    mac.power_on(0)
    mac.on_frame(Frame(dst=7, src=1, num=0, type=3, content=b"poll(2,10)"), 0, 1000, 1000)
    mac.on_timer(mac.deadline)
    mac.on_tx_done(tx_end)
    assert mac.mode == MEMBER and mac.phase == WAIT and mac.owner == 3
    return mac


def test_a_member_resyncing_takes_no_turn_until_it_hears_the_ring():
    mac = member_2()
    late = mac.deadline + 10 * TICK_HZ                     # far past R3's deadline
    assert mac.resync(late) == []
    assert mac.phase == WAIT and mac.owner is None
    # a frame from R3 (not the owner it had): not refused, no miss, and the turn goes on
    t = late + 5 * MS
    out = mac.on_frame(Frame(dst=7, src=3, num=0, type=3, content=b""), t, t + 1000, t + 1000)
    assert not [a for a in out if type(a) in (Refused, Miss)], out
    assert mac.owner == 1 and mac.phase == WAIT
    # then R1's frame gives R2 its turn, watched first: R3 does not send in it, so the ring
    # still has R2, and it raises TXEN when the watch is over
    t += 20 * MS
    out = mac.on_frame(Frame(dst=7, src=1, num=0, type=3, content=b""), t, t + 1000, t + 1000)
    assert out == [] and mac.phase == WATCH and mac.owner == 2
    assert mac.deadline == t + 1000 + mac.cfg.ttrans + max(4 * mac.cfg.byte_ticks,
                                                            mac.cfg.standby_watch)
    out = mac.on_timer(mac.deadline)
    assert any(type(a) is TxEnable and a.on for a in out) and mac.mode == MEMBER
    # the watch was for the first turn after the stall only: the next is taken at once
    mac.on_timer(mac.deadline)                          # SWITCH: the frame goes out
    mac.on_tx_done(mac.deadline or t + 40 * MS)
    t = mac.turn_start + 30 * MS
    mac.on_frame(Frame(dst=7, src=3, num=0, type=3, content=b""), t, t + 1000, t + 1000)
    out = mac.on_frame(Frame(dst=7, src=1, num=0, type=3, content=b""), t + 20 * MS,
                       t + 20 * MS + 1000, t + 20 * MS + 1000)
    assert any(type(a) is TxEnable and a.on for a in out)


def _resynced_and_watching() -> tuple[RotationalMac, int]:
    """R2 (ring {1, 2, 3}) stalled long; R1's frame, the first it hears, gives it its turn,
    which it watches: (the MAC, the End of R1's frame)."""
    mac = member_2()
    late = mac.deadline + 10 * TICK_HZ
    mac.resync(late)
    t = late + 5 * MS
    mac.on_frame(Frame(dst=7, src=1, num=0, type=3, content=b""), t, t + 1000, t + 1000)
    assert mac.phase == WATCH
    return mac, t + 1000


def test_a_member_left_out_during_its_stall_hears_the_next_robot_in_its_turn_and_listens():
    """Stopped longer than three turns, R2 was dropped; R1 and R3 go on as a ring of two, so
    R3 sends right after R1. R2 used to take the turn on its old view too (a collision at the
    bench, then it refused R3's frame and counted the father missing). Now R3's frame in the
    watched turn sends R2 back to LISTEN: nothing sent, nobody counted missing or refused."""
    mac, end = _resynced_and_watching()
    t = end + mac.cfg.ttrans + 2 * MS
    out = mac.on_frame(Frame(dst=7, src=3, num=0, type=3, content=b""), t, t + 15 * MS,
                       t + 15 * MS)
    assert mac.mode == LISTEN, out
    assert [a.reason for a in out if type(a) is ModeChange] == [
        "robot 3 sent in our first turn after a stall: the ring left us out meanwhile"]
    assert not [a for a in out if type(a) in (Refused, Miss, Transmit, TxEnable)], out
    # invited again as any listening robot is
    t += 100 * MS
    out = mac.on_frame(Frame(dst=7, src=1, num=0, type=3, content=b"poll(2,10)"), t,
                       t + 1000, t + 1000)
    assert mac.mode == MEMBER and any(type(a) is TxEnable and a.on for a in out), out


def test_a_header_coming_in_the_watched_turn_sends_it_back_to_listen():
    """The next robot's frame still coming in when the watch ends (its Header begun): the
    same verdict, before its Source is read."""
    mac, _ = _resynced_and_watching()
    out = mac.on_timer(mac.deadline, rx_busy=True)
    assert mac.mode == LISTEN
    assert not [a for a in out if type(a) in (Miss, Transmit, TxEnable)], out


def test_a_member_resyncing_that_hears_nobody_goes_back_to_listen():
    mac = member_2()
    now = mac.deadline + 5 * TICK_HZ
    mac.resync(now)
    assert mac.deadline == now + MacConfig(team=TEAM).claim_ticks(2)
    out = mac.on_timer(mac.deadline)
    assert mac.mode == LISTEN
    assert [a.reason for a in out if type(a) is ModeChange] == [
        "heard no ring since this station stalled"]
    assert not [a for a in out if type(a) in (Transmit, Miss)]


def test_a_turn_begun_on_a_stale_view_is_not_sent():
    mac = member_2()
    t = 3_000_000
    out = mac.on_frame(Frame(dst=7, src=1, num=0, type=3, content=b""), t, t + 1000, t + 1000)
    assert any(type(a) is TxEnable and a.on for a in out)      # TXEN up: our turn
    out = mac.resync(mac.deadline + TICK_HZ)
    assert [a.on for a in out if type(a) is TxEnable] == [False]
    assert mac.phase == WAIT and mac.owner is None


def test_a_listening_station_resyncing_waits_a_whole_claim_again():
    mac = RotationalMac(2, MacConfig(team=TEAM))
    mac.power_on(0)
    now = mac.deadline + TICK_HZ                # it would claim at once on its stale deadline
    assert mac.resync(now) == []
    assert mac.mode == LISTEN and mac.deadline == now + MacConfig(team=TEAM).claim_ticks(2)


# -- the station -----------------------------------------------------------------------------

def test_the_station_drops_a_frame_half_received_and_resyncs_after_its_own_frame():
    from firmware_model.mcu.scheduler import Scheduler
    sched = Scheduler()
    seen: list[object] = []
    st, radio = build_station(2, sched, config=MacConfig(team=TEAM),
                              observer=lambda s, a, now: seen.append(a))
    st.power_on()
    poll = Frame(dst=7, src=1, num=0, type=3, content=b"poll(2,10)").encode()
    st.uart.receive(poll, 0, st.uart.byte_ticks)
    while st.mac.phase != SEND:                        # TXEN up, Ttrans, the BOOT goes out
        assert sched.step()
    assert st.mac.phase == SEND
    st.resync(TICK_HZ)                                 # stalled while sending: after it
    assert st.mac.phase == SEND and [a for a in seen if type(a) is Stalled]
    sched.run_until(st.uart.busy_until + 1)
    assert st.mac.phase == WAIT and st.mac.owner is None
    # half a frame, then a stall: it is dropped, not completed by the next bytes
    t = sched.now + 10 * MS
    hb = Frame(dst=7, src=3, num=0, type=3, content=b"").encode()
    st.uart.receive(hb[:6], t, st.uart.byte_ticks)
    assert st.deframer.in_frame
    st.resync(TICK_HZ)
    assert not st.deframer.in_frame and st.stall_timer.expiry is None


def test_the_father_console_tells_a_stall_in_one_line():
    import io

    from hil.view.father import FatherConsole
    out = io.StringIO()
    FatherConsole(out, "human").ring(None, Stalled(16_320_000), 3 * TICK_HZ)
    assert out.getvalue() == ("    3.00 s  father: stalled 1.02 s (the process did not run); "
                              "what it heard meanwhile is dropped, listening for the ring "
                              "again\n")


def test_a_stall_of_a_bench_child_fails_no_order_for_silence_it_caused():
    """A ``rprs child`` with a CAN side whose process did not run for 0.6 s while a joint
    moved (CI's user-mode VM did; SIGSTOP does) failed the order ``fail(31)``: its dispatcher
    counted the stall as joint 1's silence (300 ms) and judged before the reports that came
    meanwhile were read. A stall now moves the dispatcher's clocks of silence and deadlines on
    by its length, and the order ends done."""
    from firmware_model.radio.content import cmd
    from firmware_model.radio.mac import Deliver
    from hil.bench.runner import Runner, build_child, build_submodules

    can_spec = f"virtual:stall-{id(object())}"
    runner = Runner()
    station, child = build_child(runner, 1, None, can_spec)
    subs = build_submodules(runner, can_spec)
    sched = runner.sched
    sched.post(child._on_message, Deliver(0, 1, 0, 2, (cmd("joint", 1, 12),)), 0)
    sched.after(60 * MS, time.sleep, 0.6)             # the process holds still 0.6 s
    runner.run(1.5)                                   # (and closes the buses)
    assert sched.stalls and sched.stalls[0][1] > 500 * MS
    assert subs["JOINT1"].angle_deg == 12
    assert [m.content for m in station.mac.outbox] == [b"done()joint(1,12)"], \
        child.dispatcher.log
