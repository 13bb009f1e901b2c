"""Real-time robots as separate processes on the pty radio hub, timed by a passive listener.

These take real seconds (a ring forms after |team| x Tmax of silence), so they share hubs
where they can. Turn timing is checked by medians, which hold on a loaded machine.
"""
from __future__ import annotations

import json
import re
import os
import pprint
import statistics
import subprocess
import signal
import sys
import time

import pytest

from firmware_model.mcu.ptr2000 import NEVER
from hil.bench import scripts as bench
from hil.bench.radio_hub import RadioHub
from hostload import SchedulingLatency
from processes import ATTEMPTS, disturbed, heard, ring_is, spawn, stop, wait_for

TEAM = "1,2,3,4"
"""(Tests marked ``timing`` judge hand-overs, gaps and turn order to a few ms: with two
CPU-bound programs beside them on 2 cores they failed, so they run in the timing tier.)"""


@pytest.fixture
def hub():
    h = RadioHub(nodes=6, seed=1).start()
    yield h
    h.stop()
    h.close()


@pytest.mark.timing
def test_four_child_processes_hold_the_turn_timing(hub):
    kids = [spawn("child", "--id", str(i), "--radio", hub.paths[i - 1], "--team", TEAM)
            for i in range(1, 5)]
    sniffer = bench.Sniffer(hub.paths[5]).start()
    try:
        assert wait_for(lambda: ring_is(sniffer, [1, 2, 3, 4]), 40.0), \
            [p.stderr.read() if p.poll() is not None else "" for p in kids]
        t_formed = sniffer.tick() / 16e6
        with SchedulingLatency() as probe:
            time.sleep(4.0)
        frames = [f for f in sniffer.snapshot() if f.start >= t_formed * 16e6]
    finally:
        res = sniffer.stop()
        stop(kids)
    rep = bench.cycle_report(bench.Listening(frames=frames, seconds=res.seconds))
    # A hand-over waits for two wake-ups of a robot process (its End's bytes, then its Ttrans
    # timer): on a busy host each comes late by the host's scheduling latency, measured beside
    # the ring (tests/hostload.py), which the limits allow for and the messages name. On an
    # idle machine it is a fraction of a millisecond and the limits are the spec's.
    lat = probe.result
    slack = 2 * lat.median_ms
    rep["host"] = str(lat)
    # 4 s of an idle ring of four is about 200 frames: far fewer says the sniffer stopped
    # hearing the air (its port's error, what it read), not that the ring was slow
    rep["sniffer"] = {"error": res.error, "bytes": res.bytes, "garbage": res.garbage,
                      "seconds": res.seconds}
    assert len(frames) >= 100, rep
    assert rep["robots"] == [1, 2, 3, 4], rep
    assert rep["misses"] == 0, rep         # the report names each long gap and its robots
    assert rep["turn_gap_error_ms_median"] < 3.0 + slack, rep     # Ttrans = 5 ms hand-over
    # an idle turn is 14 bytes + Ttrans: 4 robots x ~19.6 ms = 78 ms a cycle
    # (docs/protocol.md §7.2)
    for r, c in rep["cycle_ms_median"].items():
        assert 75.0 < c < 90.0 + 4 * slack, (r, c, rep)
    # every robot had its turns, in ring order (a real-time run on a busy machine may lose a
    # byte or a turn now and then: 98 % of hand-overs, not all)
    order = [f.src for f in frames]
    good = sum(1 for a, b in zip(order, order[1:]) if b == a % 4 + 1)
    assert good >= 0.98 * (len(order) - 1), (good, len(order), str(lat))


@pytest.mark.timing
def test_a_killed_child_is_dropped_and_rejoins_when_restarted(hub):
    kids = {i: spawn("child", "--id", str(i), "--radio", hub.paths[i - 1], "--team", "1,2,3")
            for i in (1, 2, 3)}
    sniffer = bench.Sniffer(hub.paths[5]).start()
    try:
        assert wait_for(lambda: ring_is(sniffer, [1, 2, 3]), 40.0)
        t_kill = sniffer.tick() / 16e6
        stop([kids[3]])
        # three missed turns of ~Tmax each, then the ring is 1 -> 2
        assert wait_for(lambda: heard(sniffer, 1, t_kill + 2.5) > 5, 10.0)
        assert heard(sniffer, 3, t_kill + 0.1) == 0
        kids[3] = spawn("child", "--id", "3", "--radio", hub.paths[2], "--team", "1,2,3")
        t_back = sniffer.tick() / 16e6
        assert wait_for(lambda: heard(sniffer, 3, t_back) > 3, 15.0)
        frames = sniffer.snapshot()
    finally:
        sniffer.stop()
        stop(kids.values())
    gaps = [(b.start - a.end) / 16e3 for a, b in zip(frames, frames[1:])
            if a.start >= (t_kill - 0.2) * 16e6 and b.start <= (t_back - 0.1) * 16e6]
    # exactly three missed turns of Tmax (600 ms) each, then robot 3 is dropped. The gaps are
    # stamped when the bytes reach this process's sniffer thread: on a loaded machine a stamp
    # can be up to ~100 ms late, which lengthens one gap and shortens the next (one run beside
    # a CPU-bound xdist worker measured only two within 590-700 ms). No other gap here comes
    # near 500 ms: a hand-over is Ttrans, a stagger at most a few Tslot.
    long_gaps = [round(g, 1) for g in gaps if g > 300]
    assert len(long_gaps) == 3 and all(500 < g < 720 for g in long_gaps), \
        [round(g, 1) for g in gaps if g > 30]


@pytest.mark.timing
def test_father_failover_between_processes(hub):
    team = "0,1,2"
    active = spawn("father", "--radio", hub.paths[0], "--team", team, "--no-input")
    kids = [spawn("child", "--id", str(i), "--radio", hub.paths[i], "--team", team)
            for i in (1, 2)]
    sniffer = bench.Sniffer(hub.paths[5]).start()
    standby = None
    try:
        assert wait_for(lambda: ring_is(sniffer, [0, 1, 2]), 40.0)
        standby = spawn("father", "--radio", hub.paths[3], "--team", team, "--standby",
                        "--no-input")
        # it follows the ring as a replica once it runs: wait for its ready line and then a
        # dozen rotations (a fixed 2 s sleep was not enough on a loaded machine, where the
        # process could still be importing when the active PC was stopped)
        ready = standby.stderr.readline()
        assert ready.startswith("father (ID 0, standby PC)"), ready
        t_ready = sniffer.tick() / 16e6
        assert wait_for(lambda: all(heard(sniffer, r, t_ready) >= 12 for r in (0, 1, 2)), 40.0)
        stop([active])
        t_kill = sniffer.tick() / 16e6
        assert wait_for(lambda: heard(sniffer, 0, t_kill + 1.0) > 10, 10.0)
        frames = [f for f in sniffer.snapshot() if f.start >= (t_kill - 0.5) * 16e6]
    finally:
        sniffer.stop()
        stop(kids + [active] + ([standby] if standby else []))
    # no turn of ID 0 was lost: no gap anywhere near Tmax (600 ms). The takeover turn is
    # late only by the standby's watch: 2 Ttrans + 4 x 30 ms in real time (docs/mac.md)
    gaps = [(b.start - a.end) / 16e3 for a, b in zip(frames, frames[1:])]
    assert max(gaps) < 250, max(gaps)
    # PC2's check turns (after a takeover, then one in eight) are late by its 30 ms watch:
    # 2 Ttrans + 30 ms = 40 ms. The median of the late hand-overs says so; a single one may
    # be later when the machine is busy (a real-time process on a shared 2-core machine).
    late = sorted(gaps)[:-1]                               # all but the takeover
    late = [g for g in late if g > 20]
    assert late and statistics.median(late) < 80, late
    order = [f.src for f in frames]
    good = sum(1 for a, b in zip(order, order[1:]) if b == (a + 1) % 3)
    assert order.count(0) > 10 and good >= 0.98 * (len(order) - 1)


def test_bench_scripts_against_the_hub(hub, tmp_path):
    # status() is answered by a child's dispatcher when its submodules answer: robot 1 gets
    # its CAN side and its submodules in a process of their own on a bus between processes
    # (virtual: alone, every answer was fail(30), "no submodule answers", and was timed)
    can = f"rprs_unix:{tmp_path / 'can1'}"
    kids = [spawn("child", "--id", "1", "--radio", hub.paths[1], "--team", "0,1,2", "--can",
                  can, "--events", stdout=subprocess.PIPE),
            spawn("child", "--id", "2", "--radio", hub.paths[2], "--team", "0,1,2", "--events",
                  stdout=subprocess.PIPE)]
    lines = _event_lines(kids)
    kids.append(spawn("submodules", "--can", can))
    try:
        link = subprocess.run([sys.executable, "-m", "hil.cli", "bench", "link", "--radio",
                               hub.paths[4], "--duration", "5", "--json"],
                              capture_output=True, text=True, timeout=60)
        rep = json.loads(link.stdout)
        assert link.returncode == 0 and rep["link_ok"]
        # every byte read is accounted for: a good frame's, garbage, or the tail of the frame
        # it began to hear mid-way (bench link left the last out of its report)
        frame_bytes = rep["bytes"] - rep["garbage_bytes"] - rep["joined_mid_frame_bytes"]
        assert 0 <= frame_bytes and rep["joined_mid_frame_bytes"] <= 576, rep
        cyc = subprocess.run([sys.executable, "-m", "hil.cli", "bench", "cycle", "--radio",
                              hub.paths[4], "--duration", "3"],
                             capture_output=True, text=True, timeout=60)
        assert cyc.returncode == 0 and "turn hand-over" in cyc.stdout, cyc.stdout + cyc.stderr

        def latency():
            """Five status() round trips, each under a second, none lost: what the ring
            gives an undisturbed bench. A child or the bench process that did not run for a
            Tslot (a stall: a starved process, about one run in 16 beside two busy loops on 2
            cores) costs a request a retry or a missed turn (0.25-0.6 s each), and a stall of
            a second drops robot 1 and fails a request: such a run is run again
            (``_judged``), named in the report."""
            mark = [len(ls) for ls in lines]
            probe = SchedulingLatency().__enter__()
            lat = subprocess.run([sys.executable, "-m", "hil.cli", "bench", "latency",
                                  "--radio", hub.paths[0], "--dst", "1", "--count", "5",
                                  "--team", "0,1,2", "--json"],
                                 capture_output=True, text=True, timeout=120)
            events = [[e for _, e in ls[m:]] for ls, m in zip(lines, mark)]
            why = disturbed(events, (), probe)
            try:
                r = json.loads(lat.stdout)
            except json.JSONDecodeError:
                return [f"no report (exit status {lat.returncode})"], why, lat.stderr[-2000:]
            if r["stalls"]:
                why.append(f"the bench process stalled {r['stalls']} times "
                           f"({r['stalled_s']} s)")
            checks = {
                "exit status 0": lat.returncode == 0,
                "5 requests, 5 replies, none lost": r["replies"] == r["sent"] == 5
                and r["loss"] == 0,
                "round trips 20 ms-1 s": r["round_trip_ms_median"] is not None
                and 20 < r["round_trip_ms_median"] <= r["round_trip_ms_p99"] < 1000,
                "no refusal": r["refused"] == 0,
            }
            return [name for name, ok in checks.items() if not ok], why, dict(
                report=r, disturbed=why)
        _judged(latency)
    finally:
        stop(kids)


def _event_lines(procs, tag=lambda: None) -> list[list[tuple[object, dict]]]:
    """The ``--events`` lines of ``procs`` (each started with its stdout a pipe), per process,
    as they come (a reader thread each), each line as ``(tag(), event)`` when it arrived."""
    import threading
    lines: list[list[tuple[object, dict]]] = [[] for _ in procs]

    def read(p, out):
        with p.stdout:
            for line in p.stdout:
                out.append((tag(), json.loads(line)))
    for p, out in zip(procs, lines):
        threading.Thread(target=read, args=(p, out), daemon=True).start()
    return lines


def test_runner_errors_are_one_line(tmp_path):
    loop = tmp_path / "loop"
    loop.symlink_to(tmp_path / "loop")          # a link to itself: "does not exist" before
    for args, needle in ((["child", "--id", "1", "--radio", "/dev/nonexistent"], "does not exist"),
                         (["child", "--id", "1", "--radio", str(loop)],
                          "is a symlink to nothing (a dangling link, or a loop of links)"),
                         (["child", "--id", "1", "--can", "socketcan:nonexist0"],
                          "cannot open CAN bus"),
                         (["father", "--radio", "/dev/nonexistent"], "does not exist"),
                         (["child", "--id", "1"], "give --radio"),
                         (["bench", "cycle", "--radio", "/dev/nonexistent"], "does not exist")):
        r = subprocess.run([sys.executable, "-m", "hil.cli", *args], capture_output=True,
                           text=True, timeout=30)
        assert r.returncode == 2 and needle in r.stderr and "Traceback" not in r.stderr, r.stderr


@pytest.mark.skipif(not hasattr(os, "killpg"), reason="needs POSIX signals")
def test_sigusr1_prints_every_threads_stack_and_the_process_goes_on(hub):
    p = spawn("child", "--id", "1", "--radio", hub.paths[0], "--team", "1,2")
    try:
        assert p.stderr.readline().startswith("running child 1")    # not a fixed sleep
        p.send_signal(signal.SIGUSR1)
        time.sleep(0.5)
        assert p.poll() is None                       # still running
    finally:
        err = stop([p])[0]
    assert "Current thread" in err or "Thread 0x" in err, err
    assert "File " in err and "run" in err, err


def test_child_stops_cleanly_on_sigterm(hub):
    """SIGTERM once the child has said it runs stops it cleanly. The test slept 1.5 s instead
    of waiting for that line, and on a loaded machine (load 12 on 2 cores) the child was
    still importing: killed, status -15. The line now comes once Ctrl-C and SIGTERM are
    handled, so a signal sent right after it stops the process cleanly."""
    for _ in range(3):
        p = spawn("child", "--id", "1", "--radio", hub.paths[0], "--can", "virtual:x")
        try:
            assert p.stderr.readline().startswith("running child 1")
            p.terminate()                         # at once: no time to settle in
            assert p.wait(timeout=10) == 0
        finally:
            err = stop([p])[0]
        assert "robot 1:" in err and "Traceback" not in err


def test_a_busy_port_is_refused_with_one_line(hub):
    from hil.bench.serial_radio import PortError, open_port
    first = open_port(hub.paths[0])
    try:
        with pytest.raises(PortError) as e:
            open_port(hub.paths[0])
        assert "busy" in str(e.value) and "\n" not in str(e.value)
        r = subprocess.run([sys.executable, "-m", "hil.cli", "child", "--id", "1", "--radio",
                            hub.paths[0]], capture_output=True, text=True, timeout=30)
        assert r.returncode == 2 and "busy" in r.stderr and "Traceback" not in r.stderr
    finally:
        first.close()


def _r1_in_ring(lines: list[str]) -> bool:
    """The father's JSON events say R1 is in its ring: R1 joined the father's ring, or the
    father joined R1's (the child started first and claimed the silent channel; in a 20x loop
    on a loaded machine the father, started last, was slow enough for that twice, and a test
    that waited only for the first case waited 40 s for nothing)."""
    return any(('"ev":"join"' in x and '"robot":1' in x) or
               ('"ev":"mode"' in x and "invited by robot 1" in x) for x in lines)


def _lines_of(proc, into: list) -> None:
    import threading

    def read() -> None:
        with proc.stdout:                     # closed at its end: nobody else reads it
            for line in proc.stdout:
                into.append(line.rstrip("\n"))
    threading.Thread(target=read, daemon=True).start()


@pytest.mark.parametrize("mode", ["human", "json"])
def test_the_father_console_follows_each_order_to_its_end(hub, tmp_path, mode):
    """rprs father printed a JSON tx line for every frame; replies and failures were buried.
    Now each order is one line per change of state, with the reason and the time it took:
    a joint move ends done (the child's done() notice), status() replied (decoded), an
    unreachable target failed with its code in words, a move to where the joint already is
    (never reported on by the child) unreported after --report-within. --exit-when-done ends
    the process when the input has ended and every order has; --json gives JSON lines only."""
    can = f"rprs_unix:{tmp_path / 'can'}"
    kids = [spawn("child", "--id", "1", "--radio", hub.paths[1], "--team", "0,1", "--can", can),
            spawn("submodules", "--can", can)]
    father = subprocess.Popen(
        [sys.executable, "-m", "hil.cli", "father", "--radio", hub.paths[0], "--team", "0,1",
         "--exit-when-done", "--report-within", "3", *(["--json"] if mode == "json" else [])],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    _lines_of(father, lines)
    try:
        def joined() -> bool:
            if mode == "human":
                return any("ring: R1 joined" in x or
                           ("father: member" in x and "ring [father 0 R1]" in x) for x in lines)
            return _r1_in_ring(lines)
        assert wait_for(joined, 40.0), lines[-5:]
        time.sleep(0.5)                                   # R1 hears its submodules' status
        # (the last: joint 2, never commanded, at rest at 45 deg by its status; a repeat of
        # joint(1,20) while joint 1 still moves would wait for its arrival, docs/dispatcher.md)
        father.stdin.write("1 joint(1,20)\n1 status()\n1 moveto(900,0,0)\n1 joint(2,45)\n")
        father.stdin.close()
        # one order failed and one ended unreported: not every order succeeded, status 1
        assert father.wait(timeout=40) == 1, father.stderr.read()
        err = father.stderr.read()
    finally:
        stop([father, *kids])
    assert "orders: 4 (done 1, replied 1, sent-only 0, failed 1, unreported 1, refused 0, " \
        "open 0)" in err, err
    # the closing line counts bad frames (a busy host may split or collide a few) on the
    # robot's line, apart from the orders' final states above
    assert re.search(r"robot 0: member, .*, bad frames \d+, ", err), err
    if mode == "json":
        evs = [json.loads(x) for x in lines]               # every line is JSON
        ends = {e["order"]: e for e in evs if e["ev"] == "order" and e["id"] < 4 and
                e["state"] in ("done", "replied", "failed")}
        assert [e["id"] for e in evs if e["ev"] == "order" and
                e["state"] == "unreported"] == [4]
        assert ends["joint(1,20)"]["state"] == "done"
        assert ends["status()"]["state"] == "replied" and "joint 2 45 deg" in \
            ends["status()"]["reply"]                   # (asked while joint 1 moves)
        assert ends["moveto(900,0,0)"]["reason"].startswith("fail(1)")
        return
    assert not [x for x in lines if x.lstrip().startswith("{")]     # no JSON, no tx lines
    text = "\n".join(lines)
    for want in ("#1 -> R1 joint(1,20): queued", "#1 -> R1 joint(1,20): sent (Number",
                 "#1 -> R1 joint(1,20): acknowledged in", "#1 -> R1 joint(1,20): done in",
                 "#2 -> R1 status(): replied in", ", joint 2 45 deg, joint 3 -90 deg",
                 "#3 -> R1 moveto(900,0,0): failed after",
                 "fail(1): target out of the arm's reach",
                 "#4 -> R1 joint(2,45): unreported after", "no report within 3 s"):
        assert want in text, (want, lines)
    assert len(lines) < 30, lines


def _order_ends(lines: list[str]) -> dict[int, list[dict]]:
    """Each order's final records (``--json``), by order id."""
    from hil.bench.orders import TERMINAL
    ends: dict[int, list[dict]] = {}
    for x in lines:
        e = json.loads(x)
        if e["ev"] == "order" and e["state"] in TERMINAL:
            ends.setdefault(e["id"], []).append(e)
    return ends


def test_piped_orders_wait_for_room_and_each_line_ends_once_with_an_honest_status(hub):
    """Issue 40, finding 2: 40 piped orders to a child with no CAN side gave 32 order records;
    the other 8 were refused ("queue full") on stderr only, and the exit status was 0 although
    every order failed. Piped input now waits for room in the queue (back pressure), every
    line gets a record with one final state (a bad line too: refused, and why), the exit
    status with --exit-when-done is 1 unless every order succeeded, and a closing line counts
    each final state."""
    kid = spawn("child", "--id", "1", "--radio", hub.paths[1], "--team", "0,1")
    orders = "1 status()\n" * 40 + "bogus line\n"
    try:
        father = subprocess.run(
            [sys.executable, "-m", "hil.cli", "father", "--radio", hub.paths[0], "--team",
             "0,1", "--json", "--exit-when-done"], input=orders, capture_output=True,
            text=True, timeout=120)
    finally:
        stop([kid])
    ends = _order_ends(father.stdout.splitlines())
    assert sorted(ends) == list(range(1, 42)), sorted(ends)
    assert all(len(v) == 1 for v in ends.values())           # one final state each
    assert {ends[i][0]["state"] for i in range(1, 41)} == {"failed"}
    # Each is the child's fail(42) (no CAN side), unless the host starved a process for
    # turns on end (a suite beside other work once did: 1 of 40): the radio's own final
    # reasons for a message the ring could not carry then are honest ends too.
    reasons = [ends[i][0]["reason"] for i in range(1, 41)]
    radio = ("destination 1 not in the ring", "no acknowledgement from 1", "expired: ")
    odd = [r for r in reasons if not r.startswith(("fail(42)",) + radio)]
    assert not odd, (odd, father.stderr)
    assert sum(r.startswith("fail(42)") for r in reasons) >= 30, (reasons, father.stderr)
    assert ends[41][0]["state"] == "refused" and ends[41][0]["dst"] is None
    assert ends[41][0]["reason"].startswith("bad order: start with the destination")
    assert "queue full" not in father.stdout + father.stderr
    assert father.returncode == 1, father.stderr
    assert "orders: 41 (done 0, replied 0, sent-only 0, failed 40, unreported 0, refused 1, "\
        "open 0)" in father.stderr, father.stderr
    # the same father exits 0 when every order succeeded (a broadcast ends sent-only)
    kid = spawn("child", "--id", "1", "--radio", hub.paths[1], "--team", "0,1")
    try:
        ok = subprocess.run([sys.executable, "-m", "hil.cli", "father", "--radio",
                             hub.paths[0], "--team", "0,1", "--quiet", "--exit-when-done"],
                            input="7 stop()\n", capture_output=True, text=True, timeout=60)
    finally:
        stop([kid])
    assert ok.returncode == 0, ok.stderr
    assert "#1 -> all stop(): sent-only" in ok.stdout, ok.stdout
    assert "orders: 1 (done 0, replied 0, sent-only 1, failed 0" in ok.stderr, ok.stderr


@pytest.mark.parametrize("mode", ["human", "json"])
def test_an_order_typed_into_a_standby_father_is_refused_at_once(hub, mode):
    """Issue 40, finding 1: an order typed into a standby PC showed "queued" and then nothing,
    for ever (and after 32 of them: "queue full"). The standby now refuses it at once and
    says where orders go: "PC2 is standing by: the active PC is PC1"; it ends refused, and
    the process's exit status says so. The standby starts once PC1's ring has formed: started
    beside it on a loaded machine, it could claim ID 0 first (PC1's imports can take seconds)
    and be the active PC, rightly."""
    team = "0,1,2"
    active = spawn("father", "--radio", hub.paths[0], "--team", team, "--no-input")
    kids = [spawn("child", "--id", str(i), "--radio", hub.paths[i], "--team", team)
            for i in (1, 2)]
    sniffer = bench.Sniffer(hub.paths[5]).start()
    try:
        formed = wait_for(lambda: ring_is(sniffer, [0, 1, 2]), 60.0)
    finally:
        sniffer.stop()
    if not formed:
        stop([active, *kids])
        pytest.fail("the ring of PC1 and children 1, 2 did not form")
    standby = subprocess.Popen(
        [sys.executable, "-m", "hil.cli", "father", "--radio", hub.paths[3], "--team", team,
         "--standby", "--exit-when-done", *(["--json"] if mode == "json" else [])],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    _lines_of(standby, lines)
    try:
        def standing_by() -> bool:
            return any("standing by" in x for x in lines)
        assert wait_for(standing_by, 40.0), lines[-5:]
        standby.stdin.write("1 status()\n")
        standby.stdin.flush()
        assert wait_for(lambda: any("refused" in x for x in lines), 20.0), lines[-5:]
        standby.stdin.close()
        assert standby.wait(timeout=20) == 1
        err = standby.stderr.read()
    finally:
        stop([standby, active, *kids])
    why = "PC2 is standing by: the active PC is PC1; give orders there"
    if mode == "json":
        ends = _order_ends(lines)
        assert list(ends) == [1] and ends[1][0]["state"] == "refused", ends
        assert ends[1][0]["reason"].startswith(why) and ends[1][0]["seconds"] == 0
        assert not [x for x in lines if '"state":"queued"' in x]
    else:
        refused = [x for x in lines if "#1 -> R1 status(): refused: " in x]
        assert len(refused) == 1 and why in refused[0], lines
        assert not [x for x in lines if "queued" in x]
    assert "refused 1, open 0)" in err, err
    assert err.startswith("father (ID 0, standby PC) on ") and \
        "orders given here are refused until it takes over" in err.splitlines()[0], err


def _stacks(procs) -> list:
    """(command, exit status, stderr) of each process; a running one is first asked for its
    threads' stacks (SIGUSR1, hil/cli) and stopped."""
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGUSR1)
    time.sleep(0.5)
    errs = stop(procs)
    return [(p.args[3], p.returncode, e[-3000:]) for p, e in zip(procs, errs)]


def _pcap(path):
    import pcapng
    ifaces, out = {}, []
    with open(path, "rb") as fh:
        for b in pcapng.FileScanner(fh):
            name = type(b).__name__
            if name == "InterfaceDescription":
                ifaces[len(ifaces)] = b.options["if_name"]
            elif name == "EnhancedPacket":
                out.append((ifaces[b.interface_id],
                            (b.timestamp_high << 32) + b.timestamp_low, bytes(b.packet_data)))
    return ifaces, out


def test_each_bench_process_captures_its_own_port_and_bus(hub, tmp_path):
    """rprs father/child/submodules --pcap: the father's and the child's radio (sent, heard)
    and the child's and the submodules' CAN bus, wall-clock ns, one order's whole path."""
    from firmware_model.radio.frame import parse_frame
    can = f"rprs_unix:{tmp_path / 'can'}"
    caps = {k: tmp_path / f"{k}.pcapng" for k in ("father", "child", "sub")}
    t_start = time.time_ns()
    kids = [spawn("child", "--id", "1", "--radio", hub.paths[1], "--team", "0,1", "--can", can,
                  "--pcap", str(caps["child"])),
            spawn("submodules", "--can", can, "--pcap", str(caps["sub"]))]
    father = subprocess.Popen(
        [sys.executable, "-m", "hil.cli", "father", "--radio", hub.paths[0], "--team", "0,1",
         "--exit-when-done", "--json", "--pcap", str(caps["father"])],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    _lines_of(father, lines)
    try:
        # on failure: the father's last events, and each other process's exit status and
        # stderr if it ended (a run in a 20x loop saw the father alone for 40 s)
        if not wait_for(lambda: _r1_in_ring(lines), 40.0):
            pytest.fail(f"R1 never joined: the father's last events {lines[-5:]}; the hub "
                        f"{hub.stats()}; the other processes and where they wait: "
                        f"{_stacks(kids)}")
        time.sleep(0.5)
        father.stdin.write("1 joint(1,20)\n")
        father.stdin.close()
        assert father.wait(timeout=40) == 0, father.stderr.read()
    finally:
        stop([father, *kids])
    t_end = time.time_ns()
    ifaces, fpk = _pcap(caps["father"])
    assert set(ifaces.values()) == {"R0 radio, sent", "R0 radio, heard"}
    sent = [parse_frame(d) for i, _, d in fpk if i == "R0 radio, sent"]
    assert sent and all(f.src == 0 for f in sent)
    assert any(f.dst == 1 and b"joint(1,20)" in f.content for f in sent), \
        [(f.dst, f.content) for f in sent][-8:]
    heard = b"".join(d for i, _, d in fpk if i == "R0 radio, heard")
    assert b"\x0f\x0a\x05" + b"0" + b"1" in heard or b"\x0f\x0a\x0571" in heard  # R1's frames
    _, cpk = _pcap(caps["child"])
    assert any(i == "R1 radio, sent" and parse_frame(d).src == 1 for i, _, d in cpk)
    can_ids = [int.from_bytes(d[:4], "big") for i, _, d in cpk if i.startswith("CAN ")]
    assert 0x101 in can_ids and 0x181 in can_ids and 0xC1 in can_ids  # command, status, done
    _, spk = _pcap(caps["sub"])
    sub_ids = [int.from_bytes(d[:4], "big") for _, _, d in spk]
    assert 0x101 in sub_ids and 0x181 in sub_ids
    for pk in (fpk, cpk, spk):
        ts = [t for _, t, _ in pk]
        assert t_start <= min(ts) and max(ts) <= t_end         # the wall clock, in ns


@pytest.mark.parametrize("pcap,words", [("-", "console"), ("/no/such/dir/x.pcapng",
                                                          "cannot write capture")])
def test_a_bad_capture_path_is_one_line(pcap, words):
    r = subprocess.run([sys.executable, "-m", "hil.cli", "child", "--id", "1", "--radio",
                        "loop://", "--pcap", pcap], capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr, r.stderr


@pytest.mark.parametrize("command", [["child", "--id", "1"], ["submodules"]])
def test_a_can_log_and_a_capture_in_one_file_are_refused_before_the_run(tmp_path, command):
    """``--can-log F --pcap F``: both writers opened the one file and the run went on, exit
    status 0; what was left was the capture's header, the CAN log was lost. Now one line,
    status 2, and nothing is written."""
    out = tmp_path / "both.log"
    r = subprocess.run([sys.executable, "-m", "hil.cli", *command, "--can",
                        "virtual:rprs-one-file", "--can-log", str(out), "--pcap", str(out),
                        "--duration", "0.5"], capture_output=True, text=True, timeout=30)
    assert r.returncode == 2, r.stderr
    assert r.stderr.splitlines() == [f"rprs: error: --can-log and --pcap name the same file "
                                     f"{out}: give each its own"]
    assert not out.exists()


class _Air:
    """A capture sink for the hub (``RadioHub.capture``): every packet on the hub's air as
    (node or "foreign", start, end, collided), in the air's own ticks, so that a late thread of
    the test process cannot move what is measured."""

    tsresol = 9
    epoch_units = 0

    def __init__(self, hub):
        self.hub = hub
        self.packets: list[tuple[object, int, int, bool]] = []

    def follow(self, clock):
        pass

    def radio(self, key, tick, data, comment=None):
        start = tick - len(data) * self.hub.byte_ticks
        self.packets.append((key, start, tick, bool(comment and "collided" in comment)))


def _children_on_hub(hub, ids, team: str, tag=lambda: None):
    """``rprs child --events`` for each robot of ``ids`` on the hub's nodes in order; returns
    the processes and, per child, its event lines as they come (a reader thread each), each
    line as ``(tag(), event)`` when it arrived (``tag`` says e.g. whether bursts had begun)."""
    kids = [spawn("child", "--id", str(r), "--radio", hub.paths[i], "--team", team, "--events",
                  stdout=subprocess.PIPE) for i, r in enumerate(ids)]
    return kids, _event_lines(kids, tag)


def _ring_of_three_formed(air) -> bool:
    """The last six good frames on the hub's air go round nodes 0, 1, 2 twice."""
    srcs = [k for k, s, e, c in list(air.packets)[-6:] if not c]
    return srcs in ([0, 1, 2] * 2, [1, 2, 0] * 2, [2, 0, 1] * 2)


def _judged(scenario):
    """Runs ``scenario()`` (returns the names of its failed checks, why the run was disturbed
    (``processes.disturbed``) and a report) until a run passes: a run that failed a check and
    was disturbed is run again, up to ``ATTEMPTS`` runs in all; a failed check in an
    undisturbed run fails at once. The failure lists every run's checks and report."""
    runs = []
    for _ in range(ATTEMPTS):
        failed, why, report = scenario()
        if not failed:
            return
        runs.append((failed, report))
        if not why:
            break
    pytest.fail("; ".join(runs[-1][0]) + ":\n" + pprint.pformat(runs, width=100))


class _Watched:
    """The children of a scenario on ``hub`` with the host's latency probed beside them:
    ``kids`` and their ``lines`` (``_children_on_hub``, tagged with ``armed()``, by default
    ``hub.armed``); ``end()``
    stops the children, the probe and the hub and returns the children's stderr, and
    ``why()`` says whether the run, from arming on, got the CPU its margins assume."""

    def __init__(self, hub, ids, team: str, armed=None):
        self.hub = hub
        self.probe = SchedulingLatency().__enter__()
        self.kids, self.lines = _children_on_hub(hub, ids, team,
                                                 tag=armed or (lambda: hub.armed))
        self.hub_lates: list = []

    def end(self) -> list[str]:
        errs = stop(self.kids)
        self.probe.stop()
        self.hub_lates = list(self.hub.sched.lates) if self.hub.sched is not None else []
        self.hub.stop()
        self.hub.close()
        return errs

    def armed_events(self, kinds) -> list[dict]:
        return [e for ls in self.lines for armed, e in ls if armed and e["ev"] in kinds]

    def why(self) -> list[str]:
        return disturbed([[e for armed, e in ls if armed] for ls in self.lines],
                         self.hub_lates, self.probe)


class _BreakingHub(RadioHub):
    """A hub that, once armed, breaks ``count`` frames with a 4 ms burst on its air, in the
    air's own thread and ticks: the first frame that starts ``every`` ticks or more after the
    previous burst and is sent by the next node of ``order`` (node indices, in turn) gets the
    burst 3 ms after its first byte. ``first`` is the tick of the first burst, ``bursts`` the
    ticks of all, ``broken`` whose frame each broke.

    Aimed, not periodic: bursts at times of the wall clock's choosing hit the frame before
    robot 6's turn in some runs and never in others; aimed in turn at each robot's frame, every
    run breaks the frame before robot 6's a third of the times."""

    BREAK_AFTER = 3 * 16_000                          # ticks (3 ms) into the broken frame

    def __init__(self, *args, count, every, order, **kw):
        super().__init__(*args, **kw)
        self.armed = False
        self.count = count
        self.every = every
        self.order = order
        self.first: int | None = None
        self.bursts: list[int] = []
        self.broken: list[int] = []

    def _send(self, i):
        starts = self._radios[i].rx_from != NEVER     # a burst from a node that was listening
        t0 = max(self._sched.now, self._tx_end[i])
        super()._send(i)
        if not (self.armed and starts and len(self.bursts) < self.count):
            return
        if i != self.order[len(self.bursts) % len(self.order)]:
            return
        if self.bursts and t0 < self.bursts[-1] + self.every:
            return
        at = t0 + self.BREAK_AFTER
        self.bursts.append(at)
        self.broken.append(i)
        if self.first is None:
            self.first = at
        self.sched.at(at, self.air.burst, 0.004)


def _silences(packets, since):
    """Each silence on the air from ``since`` on, as (ms, whose packet it follows, whose it
    ends): from the latest end of any packet before (a frame the burst broke goes on after the
    burst) to the next packet's start."""
    out, last_end, last_key = [], None, None
    for key, start, end, _ in sorted(packets, key=lambda p: p[1]):
        if last_end is not None and start >= since and start > last_end:
            out.append(((start - last_end) / 16_000, last_key, key))
        if last_end is None or end > last_end:
            last_end, last_key = end, key
    return out


def _robot_6_after_bursts():
    """One run of the scenario below: what the hub's air and the children said."""
    tb = 16_000_000
    hub = _BreakingHub(nodes=3, seed=1, count=12, every=tb * 73 // 100, order=(0, 1, 2))
    air = _Air(hub)
    hub.capture(air)
    hub.start()
    probe = SchedulingLatency().__enter__()
    logs, lines = _children_on_hub(hub, (1, 2, 6), "1,2,6")
    try:
        assert wait_for(lambda: _ring_of_three_formed(air), 40.0), "the ring 1, 2, 6 did not form"
        hub.armed = True
        assert wait_for(lambda: len(hub.bursts) == hub.count, 30.0), \
            f"{len(hub.bursts)} of {hub.count} frames broken"
        last = hub.bursts[-1]
        assert wait_for(lambda: air.packets and air.packets[-1][2] > last + tb, 10.0)
        alive = [p.poll() is None for p in logs]
    finally:
        errs = stop(logs)
        probe.stop()
        hub_lates = list(hub.sched.lates) if hub.sched is not None else []
        hub.stop()
        hub.close()
    assert alive == [True] * 3, errs
    events = [[e for _, e in ls] for ls in lines]
    why = disturbed(events, hub_lates, probe)
    names = {0: 1, 1: 2, 2: 6, "foreign": "burst"}
    packets = list(air.packets)
    assert len([p for p in packets if p[0] == "foreign"]) == hub.count
    hits = {names[p[0]] for p in packets
            if p[2] >= hub.first and p[0] != "foreign" and p[3]}
    gaps = [(ms, names[a], names[b]) for ms, a, b in _silences(packets, hub.first)]
    checks = {
        "the bursts broke frames of robots 1, 2 and 6": hits == {1, 2, 6},
        "no silence of Tmax on the air": not [g for g in gaps if g[0] >= 600.0],
        "robot 6 waited out its 6 Tslot": any(g[2] == 6 and g[0] > 5 * 80 for g in gaps),
        "nobody dropped": not [e for ls in events for e in ls if e["ev"] == "disable"],
    }
    report = dict(longest=sorted(gaps)[-5:], disturbed=why,
                  events=[[e for e in ls if e["ev"] not in ("tx",)] for ls in events])
    return [name for name, ok in checks.items() if not ok], why, report


@pytest.mark.timing
def test_a_healthy_robot_6_keeps_its_turn_after_bursts_on_the_hub():
    """Issue 40 at the bench: children 1, 2 and 6 on the hub; once the ring has formed, 4 ms
    bursts break 12 frames, at least 0.73 s apart, robot 1's, 2's and 6's in turn. A burst that
    breaks a frame closes its turn uncertainly, and the next owner waits id x Tslot
    (R-stagger): after robot 2's broken frame robot 6 waits 6 Tslot. With the real-time Tslot
    of 100 ms its Header began after the others' closure + Tmax: they counted it missing (9-11
    times in 28 s) and took the turn at closure + Tmax + Ttrans. Judged on the hub's own air
    clock: once the bursts begin, no silence on the air lasts Tmax (600 ms; robot 6's stagger
    now leaves one of about 513 ms after robot 2's frame: 20 ms quiet gap + 6 x 80 ms + Ttrans
    + the processes' latency), robot 6 did take turns after its stagger, and nobody is dropped.

    The margin left, 86 ms, is for two pty hops and the processes' timers: a run in which a
    process or the host was more than 20 ms late (``processes.disturbed``) and a check failed
    is run again, up to three times in all; a failed check in an undisturbed run fails at
    once."""
    _judged(_robot_6_after_bursts)


CUT_OFF = bytes.fromhex("0f0a05373230303330353632")
"""A Header whose Length promises 562 bytes, then nothing (issue 40, finding 5)."""


class _Answerer(_Air):
    """The capture sink of ``_Air`` that also answers the next ``left`` invitations of robot 5
    on the hub's air with ``CUT_OFF``, Ttrans after the inviting frame ends (in air ticks),
    once armed; ``sent`` holds the air tick at which each went on air."""

    def __init__(self, hub, left):
        super().__init__(hub)
        self.armed = False
        self.left = left
        self.sent: list[int] = []

    def radio(self, key, tick, data, comment=None):
        super().radio(key, tick, data, comment)
        if self.armed and self.left and key != "foreign" and comment is None and \
                b"poll(5," in data:
            self.left -= 1
            self.hub.sched.at(tick + 80_000, self._answer)

    def _answer(self):
        self.sent.append(self.hub.sched.now)
        self.hub.air.inject(CUT_OFF)


def _cut_off_headers():
    """One run of the scenario below."""
    hub = RadioHub(nodes=3, seed=1)
    air = _Answerer(hub, left=8)
    hub.capture(air)
    hub.start()
    run = _Watched(hub, (1, 3, 4), "1,3,4,5", armed=lambda: air.armed)
    try:
        assert wait_for(lambda: _ring_of_three_formed(air), 40.0), "the ring 1, 3, 4 did not form"
        air.armed = True
        assert wait_for(lambda: len(air.sent) == 8, 30.0), air.sent
        time.sleep(1.5)
        alive = [p.poll() is None for p in run.kids]
    finally:
        errs = run.end()
    assert alive == [True] * 3, errs
    packets = sorted(air.packets, key=lambda p: p[1])
    waits = []
    for t in air.sent:
        nxt = min(s for k, s, e, c in packets if k != "foreign" and s > t and not c)
        waits.append((nxt - t) / 16_000)
    # A lone miss of a healthy robot can still happen on a loaded bench (robot 3 refusing
    # robot 1's frame as robot 4's turn; docs/guarantees.md, "Open at the bench"): never two
    # in a row.
    events = run.armed_events(("miss", "disable"))
    twice = []
    for by in (1, 3, 4):
        seen = [e for e in events if e["by"] == by and e["robot"] != 5]
        twice += [(by, a["robot"]) for a, b in zip(seen, seen[1:])
                  if a["robot"] == b["robot"] and b["t"] - a["t"] < 16_000_000 * 3 // 2]
    checks = {
        "the next good frame began within 400 ms of each answer": max(waits) < 400.0,
        "nobody but robot 5 dropped": not [e for e in events
                                           if e["ev"] == "disable" and e["robot"] != 5],
        "no robot counted the same robot missing twice in a row": not twice,
    }
    report = dict(waits_ms=waits, events=events, disturbed=run.why())
    return [name for name, ok in checks.items() if not ok], report["disturbed"], report


@pytest.mark.timing
def test_a_cut_off_header_answering_invitations_costs_its_bytes_on_the_hub():
    """Issue 40, finding 5, at the bench: children 1, 3 and 4 (team 1, 3, 4, 5: robot 4 invites
    the absent 5), and a transmitter on the hub's air answering 8 invitations with a Header
    that promises 562 bytes and stops after 12. The turn used to close at the promised End:
    about 690 ms of silence each time (594 ms + R-stagger). Now the bytes stop, the frame is over
    one stall gap later and the next owner (robot 1) begins after its R-stagger: judged on the
    hub's air clock, the next good frame starts within 400 ms of each answer's start (20 ms
    stall gap + 80 ms Tslot + Ttrans + the processes' latency), and nobody is dropped. A run
    the host disturbed (``processes.disturbed``) that fails a check is run again (``_judged``)."""
    _judged(_cut_off_headers)


BURST_TICKS = 100_002
"""``burst@T:0.006``: 6 bytes at 16667 ticks."""
BEFORE_END = 21_002
"""Ticks (1.3 ms) before a frame's end on air at which ``_TailHub`` begins its burst: the burst
breaks the frame's last bytes and ends 79,000 ticks after the frame, 1,000 ticks (62.5 us)
before the sender's Ttrans (80,000 ticks) is over."""


class _TailHub(RadioHub):
    """A hub that, once armed, puts a 6 ms burst on its air over the end of a robot's frame
    (from ``BEFORE_END`` ticks before it ends), ``left`` times at least ``every`` ticks apart,
    in the air's own thread and ticks; ``at`` holds the ends of the frames it broke."""

    def __init__(self, *args, left, every, **kw):
        super().__init__(*args, **kw)
        self.armed = False
        self.left = left
        self.every = every
        self.at: list[int] = []

    def _send(self, i):
        super()._send(i)
        end = self._tx_end[i]
        if self.armed and self.left and not self._pending[i] and \
                (not self.at or end >= self.at[-1] + self.every):
            self.left -= 1
            self.at.append(end)
            self.sched.at(end - BEFORE_END, self.air.burst, 0.006)


def _bursts_over_frame_ends():
    """One run of the scenario below."""
    hub = _TailHub(nodes=3, seed=1, left=12, every=16_000_000 * 2 // 5)
    air = _Air(hub)
    hub.capture(air)
    hub.start()
    run = _Watched(hub, (1, 2, 6), "1,2,6")
    try:
        assert wait_for(lambda: _ring_of_three_formed(air), 40.0), "the ring 1, 2, 6 did not form"
        hub.armed = True
        assert wait_for(lambda: len(hub.at) == 12, 30.0), hub.at
        time.sleep(1.5)
        alive = [p.poll() is None for p in run.kids]
    finally:
        errs = run.end()
    assert alive == [True] * 3, errs
    bursts = [(s, e) for k, s, e, c in air.packets if k == "foreign"]
    assert bursts == [(t - BEFORE_END, t - BEFORE_END + BURST_TICKS) for t in hub.at]
    # Judged from the first frame aimed at on: a collision of joiners while the ring formed
    # (before the hub was armed) is not one of the bursts'.
    broken = {e for k, s, e, c in air.packets if k != "foreign" and c and e >= hub.at[0]}
    assert broken == set(hub.at)                 # each broke the end of the frame it aimed at
    events = run.armed_events(("miss", "disable"))
    report = dict(events=events, disturbed=run.why(),
                  silences=sorted(_silences(air.packets, hub.at[0]))[-5:])
    failed = ["a child counted a robot missing or dropped one"] if events else []
    return failed, report["disturbed"], report


@pytest.mark.timing
def test_no_healthy_robot_is_counted_missing_after_a_burst_over_a_frame_end_on_the_hub():
    """Issue 40 at the bench: a 6 ms burst over a robot's last 1.3 ms on air that goes on for
    4.94 ms after, just less than Ttrans. Its sender dated its End earlier than the air (its
    bytes reach the air late), so its radio model listened again while the collision was still
    on air: the hub, which made no node deaf, gave it the garbage, which it took for its
    successor's broken frame (clause 42); the successor, whose turn followed a broken frame,
    began after its R-stagger, and the sender refused its good frame as out of turn and
    counted the next robot missing (clause 39). A PTR2000 is deaf until 3 ms (the nRF401's
    TX->RX switch time) after its last byte left: the hub now deafens a node so on the air's
    clock, and of the garbage the sender hears at most the burst's last 1.94 ms, before its
    End + Ttrans on the air's clock. Children 1, 2 and 6, twelve such bursts: no child counts
    anyone missing once the ring has formed, and nobody is dropped (the simulator's
    prediction: tests/docs/test_margin_bounds.py).

    After robot 2's broken frame robot 6's staggered Header leaves 86 ms of Tmax for the pty
    hops and the processes' timers (docs/protocol.md §7.6): a run the host disturbed
    (``processes.disturbed``) that fails is run again (``_judged``)."""
    _judged(_bursts_over_frame_ends)


LATE_BURST = 80_000 + 80_000
"""Ticks after robot 6's frame ends on air at which ``_LateHub`` begins its 4 ms burst: Ttrans
and 5 ms more, well after robot 1's turn began (and Ttrans) in every child's own clock."""
LATE_BY = 480_000
"""Ticks (30 ms, more than the real-time quiet gap) after that burst at which robot 1's bytes
reach the air: a PC whose frame comes late."""


class _LateHub(RadioHub):
    """A hub that, once armed, puts a 4 ms burst in the hand-over from robot 6 (node 2) to robot
    1 (node 0), ``LATE_BURST`` ticks after robot 6's frame ends, and holds robot 1's next bytes
    until ``LATE_BY`` ticks after the burst (node 0 listens until they go on air, as the hub
    does for any node): ``left`` times, at least ``every`` ticks apart; ``at`` holds the ends
    of robot 6's frames."""

    def __init__(self, *args, left, every, **kw):
        super().__init__(*args, **kw)
        self.armed = False
        self.left = left
        self.every = every
        self.at: list[int] = []

    def _send(self, i):
        super()._send(i)
        end = self._tx_end[i]
        if i == 2 and self.armed and self.left and not self._pending[i] and \
                (not self.at or end >= self.at[-1] + self.every):
            self.left -= 1
            self.at.append(end)
            self.sched.at(end + LATE_BURST, self.air.burst, 0.004)
            self._tx_end[0] = max(self._tx_end[0], end + LATE_BURST + 66_668 + LATE_BY)


def _late_headers_after_bursts():
    """One run of the scenario below."""
    from hil.bench.runner import REALTIME_MARGINS
    hub = _LateHub(nodes=3, seed=1, left=10, every=16_000_000 * 2 // 5)
    air = _Air(hub)
    hub.capture(air)
    hub.start()
    run = _Watched(hub, (1, 2, 6), "1,2,6")
    try:
        assert wait_for(lambda: _ring_of_three_formed(air), 40.0), "the ring 1, 2, 6 did not form"
        hub.armed = True
        assert wait_for(lambda: len(hub.at) == 10, 30.0), hub.at
        time.sleep(1.5)
        alive = [p.poll() is None for p in run.kids]
    finally:
        errs = run.end()
    assert alive == [True] * 3, errs
    packets = list(air.packets)
    bursts = [s for k, s, e, c in packets if k == "foreign"]
    assert len(bursts) == 10 and all(b >= t + LATE_BURST for t, b in zip(hub.at, bursts))
    late = [min(s for k, s, e, c in packets if k == 0 and not c and s >= b) - (b + 66_668)
            for b in bursts]
    # What the scenario needs: robot 1's Header after the real-time quiet gap closed the
    # burst's turn (the hub holds its bytes LATE_BY after the burst; once, on a quiet machine,
    # robot 1's clean frame began 1.3 ms before that: why is not known)
    assert all(d > REALTIME_MARGINS["quiet_gap"] for d in late), late
    # robot 6 took robot 1's late frame for robot 1's: it never counted robot 2 missing
    # (before clause 42's rule, it did after nearly every one of these hand-overs). Other
    # misses a loaded machine can cause (a frame split by more than the stall gap on its way
    # through the ptys) are not this test's: docs/guarantees.md, "At the bench".
    events = [e for armed, e in run.lines[2] if armed and e["ev"] in ("miss", "disable")
              and e["robot"] == 2]
    report = dict(events=events, disturbed=run.why())
    failed = ["robot 6 counted robot 2 missing or dropped it"] if events else []
    return failed, report["disturbed"], report


@pytest.mark.timing
def test_a_late_header_after_a_burst_in_the_hand_over_costs_nobody_a_miss_on_the_hub():
    """Issue 40 at the bench, the last false misses: a burst in the hand-over from robot 6 to
    robot 1, after robot 1's turn began, is taken for robot 1's broken frame and its turn
    closes at quiet (clause 42); robot 1's Header, late as a PC's can be, comes 30 ms after the
    burst. Robot 6, waiting for robot 2's staggered turn, refused it as out of turn and counted
    robot 2 missing (robot 2 itself followed it). Clause 42 now takes it for robot 1's frame.
    Children 1, 2 and 6, ten such hand-overs: robot 6 never counts robot 2 missing (the
    simulator's case: tests/docs/test_margin_bounds.py). A run the host disturbed
    (``processes.disturbed``) that fails is run again (``_judged``)."""
    _judged(_late_headers_after_bursts)


@pytest.mark.parametrize("spec,words", [
    ("socket://:99999", "PORT 1-65535"), ("socket://localhost", "needs HOST:PORT"),
    ("socket://host:port", "got 'port'"), ("rfc2217://", "rfc2217:// needs HOST:PORT")])
def test_a_socket_url_without_a_port_it_can_use_says_so(spec, words):
    """pyserial answers these with "'debug|info|warning|error'" (an outside check)."""
    from hil.bench.serial_radio import PortError, open_port
    with pytest.raises(PortError, match=words):
        open_port(spec)
