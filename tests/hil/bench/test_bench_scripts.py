"""The bench scripts' reports (hil/bench/scripts.py): what they count is what happened."""
from __future__ import annotations

import os
import time

import pytest

from firmware_model.radio.frame import Frame
from firmware_model.timing import TICK_HZ
from hil.bench import scripts as bench
from hil.bench.scripts import HeardFrame, Listening
from processes import sigstop

MS = TICK_HZ // 1000
BT = 16667


def _frame(src, start, nbytes=14, invites=False):
    return HeardFrame(src, 7, 0, 3, nbytes, start, start + nbytes * BT, invites)


def test_cycle_report_keeps_invitation_windows_apart_from_hand_overs():
    """The 50 ms window after a poll was once reported as a 50.5 ms hand-over 'error' (p99)."""
    frames, t = [], 0
    for k in range(40):
        invites = k % 10 == 0                 # the father invites every tenth frame
        f = _frame(0 if k % 2 == 0 else 1, t, invites=invites)
        frames.append(f)
        t = f.end + (50 * MS if invites else 5 * MS + (k % 3) * MS // 10)
    rep = bench.cycle_report(Listening(frames=frames, seconds=2.0))
    assert rep["invitation_windows"] == 4
    assert abs(rep["invitation_gap_ms_median"] - 50.0) < 0.01
    assert rep["turn_gap_error_ms_p99"] < 0.3 and rep["misses"] == 0
    assert abs(rep["turn_gap_ms_median"] - 5.1) < 0.11


def test_no_turn_across_the_listeners_own_stall_is_judged():
    """``rprs bench cycle`` SIGSTOPped for 2 s counted a missed turn on a healthy ring: the
    frames after the stall, read at once, stood 2 s after the last one before it."""
    frames, t = [], 0
    for k in range(20):
        f = _frame(k % 2, t)
        frames.append(f)
        t = f.end + 5 * MS + (2000 * MS if k == 9 else 0)     # the listener stopped after 9
    stall = (frames[9].end + MS, frames[10].start - MS)
    rep = bench.cycle_report(Listening(frames=frames, seconds=5.0))
    assert rep["misses"] == 1 and rep["stalls"] == 0          # (without the stall said)
    rep = bench.cycle_report(Listening(frames=frames, seconds=5.0, stalls=[stall]))
    assert rep["misses"] == 0 and rep["stalls"] == 1 and abs(rep["stalled_s"] - 1.998) < 0.01
    assert rep["turn_gap_error_ms_p99"] < 0.01


@pytest.mark.timing
@pytest.mark.skipif(not os.path.isdir("/proc/self/task"),
                    reason="needs /proc to see that a stopped process's threads all stopped")
def test_the_sniffer_says_when_it_did_not_run():
    """A listener thread that does not run for longer than SNIFFER_STALL_TICKS (its reads
    return every 50 ms at most) records the span, and drops what it read then."""
    import signal
    import subprocess
    import sys
    master, slave = os.openpty()
    code = ("import os, sys, time, json\n"
            "from hil.bench import scripts as b\n"
            f"s = b.Sniffer(os.ttyname({slave})).start()\n"
            "print('go', flush=True); time.sleep(2.5)\n"
            "r = s.stop(); print(json.dumps([r.stalls, r.bytes]))\n")
    p = subprocess.Popen([sys.executable, "-c", code], pass_fds=(slave,), text=True,
                         stdout=subprocess.PIPE)
    try:
        assert p.stdout.readline() == "go\n"
        time.sleep(0.5)
        sigstop(p)           # (every thread stopped: else the frame is read in time)
        os.write(master, Frame(src=2, dst=7, num=3, type=3, content=b"").encode())
        time.sleep(0.8)
        p.send_signal(signal.SIGCONT)
        import json
        stalls, nbytes = json.loads(p.stdout.readline())
    finally:
        p.wait(timeout=10)
        os.close(master)
        os.close(slave)
    assert any(0.6 < (t1 - t0) / TICK_HZ < 2.0 for t0, t1 in stalls), stalls
    assert nbytes == 0                   # read after the stall: dropped, its times unknown


def test_the_sniffer_discards_what_waited_in_the_port_before_it_started():
    """Bytes left in the port before the bench listens, and the tail of a frame it came in on,
    are not the ring's garbage; garbage between good frames is."""
    master, slave = os.openpty()
    try:
        sn = bench.Sniffer(os.ttyname(slave))
        os.write(master, b"stale bytes from an earlier run\x00\xff")
        time.sleep(0.05)
        sn.start()
        good = Frame(src=2, dst=7, num=3, type=3, content=b"").encode()
        os.write(master, good[5:] + good + b"\x00\x01" + good)   # joins mid-frame
        deadline = time.monotonic() + 5.0
        while len(sn.snapshot()) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        res = sn.stop()
    finally:
        os.close(master)
        os.close(slave)
    assert [(f.src, f.num) for f in res.frames] == [(2, 3), (2, 3)]
    assert res.joined_mid_frame == len(good) - 5      # the tail of a frame we came in on
    assert res.garbage == 2 and res.failed == 0       # between the good frames


def test_noise_before_any_frame_is_garbage_not_a_frame_joined_late():
    """A channel of noise alone (``rprs radio-hub --noise``, nobody sending): ``bench link``
    said ``SILENT ... 0 garbage bytes`` and ``bench cycle`` counted it all as the tail of a
    frame it came in on. Only a first run of one frame's worth is that; the rest is garbage,
    and ``link`` says it heard bytes but no frame."""
    master, slave = os.openpty()
    try:
        sn = bench.Sniffer(os.ttyname(slave)).start()
        os.write(master, bytes(range(0x20, 0x7f)) * 10)            # 950 bytes, no Header
        time.sleep(0.3)
        os.write(master, b"\x00\x01\x02")                         # a later burst
        deadline = time.monotonic() + 5.0
        while sn.result.bytes < 953 and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.1)
        res = sn.stop()
    finally:
        os.close(master)
        os.close(slave)
    assert res.bytes == 953 and not res.frames
    assert res.joined_mid_frame == bench.MAX_FRAME_BYTES
    assert res.garbage == 953 - bench.MAX_FRAME_BYTES


class _Station:
    """What ``latency`` uses of a station: its ID, ``submit`` and its list of observers."""

    def __init__(self, submit=None) -> None:
        self.id, self.submit, self.observers = 0, submit, []

    def add_observer(self, fn, first: bool = False) -> None:
        self.observers.insert(0 if first else len(self.observers), fn)

    def remove_observer(self, fn) -> None:
        self.observers.remove(fn)

    def tell(self, a, now: int) -> None:
        for fn in self.observers:
            fn(self, a, now)


def test_latency_tells_a_refusal_from_a_status_reply_and_skips_broadcasts():
    """A radio-only child answers status() with fail(42)status(): that was once counted as
    "3/3 status replies"; and an act(n,1) broadcast from the robot counted as a reply."""
    from types import SimpleNamespace

    from firmware_model.radio.content import cmd
    from firmware_model.radio.frame import BROADCAST
    from firmware_model.radio.mac import Deliver, Outcome

    station = _Station()
    sched = SimpleNamespace(now=0)
    answers = iter([(cmd("fail", 42), cmd("status")),
                    (cmd("joint", 1, 0), cmd("joint", 2, 45))])

    def submit(dst, commands, type_):
        msg = SimpleNamespace(state="delivered")
        sched.now += 10 * MS
        station.tell(Deliver(2, BROADCAST, 9, 3, (cmd("act", 1, 1),)), sched.now)
        station.tell(Outcome(msg, True, ""), sched.now)
        station.tell(Deliver(2, 0, 1, 3, next(answers)), sched.now)
        return msg
    sched.post = lambda fn, *args: fn(*args)
    station.submit = submit
    r = bench.latency(SimpleNamespace(sched=sched), station, 2, 2, 1.0)
    assert (r.sent, r.replies) == (2, 2)
    assert r.refusals == ["fail(42)status(): the child has no CAN side"]
    assert station.observers == []           # it stopped watching when it was done


def _latency_a_second_apart(station, sched, submit):
    """``bench.latency`` for two requests to robot 2, each a second after the last, its
    answers what ``submit`` tells the station (an ack wait of 50 ms)."""
    from types import SimpleNamespace

    def post(fn, *args):
        sched.now += 1000 * MS
        fn(*args)
    sched.post = post
    station.submit = submit
    return bench.latency(SimpleNamespace(sched=sched), station, 2, 2, 0.05)


def test_a_late_reply_to_a_request_that_timed_out_is_not_the_next_ones():
    """``latency`` took the first message from the robot after a request for its reply: the
    late reply to a request that had timed out, heard after the next request went out, was
    credited to that one, with a round trip too short. A reply is the request's only if it
    was heard no earlier than the frame that acknowledged the request."""
    from types import SimpleNamespace

    from firmware_model.radio.content import cmd
    from firmware_model.radio.mac import Deliver, Outcome

    station = _Station()
    sched = SimpleNamespace(now=0)
    calls = []

    def submit(dst, commands, type_):
        msg = SimpleNamespace(state="delivered")
        calls.append(msg)
        t = sched.now                                 # (each request a second later)
        if len(calls) == 1:                           # acknowledged, its reply late
            station.tell(Outcome(msg, True, ""), t + 20 * MS)
        else:
            station.tell(Deliver(2, 0, 1, 3, (cmd("joint", 1, 0),)), t + 5 * MS)  # #1's
            station.tell(Outcome(msg, True, ""), t + 20 * MS)
            station.tell(Deliver(2, 0, 2, 3, (cmd("joint", 1, 0),)), t + 40 * MS)
        return msg

    r = _latency_a_second_apart(station, sched, submit)
    assert (r.sent, r.replies) == (2, 1)
    assert r.round_trip_ms == [40.0]


def test_a_reply_heard_before_its_acknowledgement_is_the_requests_when_none_is_owed():
    """The father missed the frame that acknowledged a request (a starved process on a busy
    host); the robot's reply came, then the acknowledgement again: the reply, heard before
    the acknowledgement, was taken for a late one to an earlier request that had none
    outstanding, and ``bench latency`` reported 4 replies of 5 with no loss to explain it.
    It is this request's while every earlier one was answered."""
    from types import SimpleNamespace

    from firmware_model.radio.content import cmd
    from firmware_model.radio.mac import Deliver, Outcome

    station = _Station()
    sched = SimpleNamespace(now=0)

    def submit(dst, commands, type_):
        msg = SimpleNamespace(state="delivered")
        t = sched.now
        station.tell(Deliver(2, 0, 1, 3, (cmd("joint", 1, 0),)), t + 30 * MS)   # the reply
        station.tell(Outcome(msg, True, ""), t + 60 * MS)    # the acknowledgement, again
        return msg

    r = _latency_a_second_apart(station, sched, submit)
    assert (r.sent, r.replies) == (2, 2)
    assert r.round_trip_ms == [30.0, 30.0]


def test_a_listener_whose_port_goes_away_stops_and_says_so(capsys, monkeypatch):
    """The radio hub stopped under 'rprs bench link': it once listened on to the end of
    --duration and reported a whole run, exit 0."""
    import tty

    from hil.cli import main
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    real = bench.Sniffer.start

    def start(self):
        started = real(self)
        os.close(master)                     # the hub goes away once we listen
        return started
    monkeypatch.setattr(bench.Sniffer, "start", start)
    try:
        code = main(["bench", "link", "--radio", path, "--duration", "120"])
    finally:
        os.close(slave)
    out, err = capsys.readouterr()
    assert code == 1, out + err
    assert out.startswith("link SILENT: 0 bytes in "), out
    assert err.splitlines()[-1].startswith(f"rprs: error: the radio port {path} went away "
                                           f"after "), err


def test_latency_stops_asking_once_the_runner_has_stopped():
    """With its port gone (the runner stopped), 'rprs bench latency --count 200' waited
    5 s for each request that could no longer be sent."""
    import threading
    from types import SimpleNamespace

    finished = threading.Event()
    finished.set()
    station = _Station()
    runner = SimpleNamespace(sched=SimpleNamespace(now=0, post=lambda fn, *a: None),
                             finished=finished)
    r = bench.latency(runner, station, 1, 200, 10.0)
    assert (r.sent, r.replies, r.failed) == (0, 0, [])


def test_a_request_the_runner_takes_late_does_not_answer_for_the_next_one():
    """``latency`` gives up on a request the runner's thread has not taken in 5 s; that
    request's callback once wrote into the next request's box (a closure over the loop's
    variables), so the next request was judged by the late one's result."""
    import threading
    from types import SimpleNamespace

    posted: list = []
    both = threading.Condition()

    def post(fn, *args):
        with both:
            posted.append((fn, args))
            both.notify()

    def runner_thread():                  # takes nothing until the second request is posted
        with both:
            both.wait_for(lambda: len(posted) == 2, timeout=60)
        for fn, args in posted:
            fn(*args)

    answers = iter([ValueError("the late request"), SimpleNamespace(state="delivered")])

    def submit(dst, commands, type_):
        a = next(answers)
        if isinstance(a, Exception):
            raise a
        return a
    station = _Station(submit)
    runner = SimpleNamespace(sched=SimpleNamespace(now=0, post=post))
    th = threading.Thread(target=runner_thread, daemon=True)
    th.start()
    r = bench.latency(runner, station, 1, 2, 0.2)
    th.join(10)
    assert r.failed == ["None"], r             # the first: not taken within 5 s
    assert r.sent == 1, r                      # the second: its own request, sent
