"""The same scenario in both worlds: a foreign burst over a hand-over of a two-member ring, in
the simulator and on the pty radio hub with real ``rprs child`` processes (issue: "the
simulator predicts the bench"; the original finding was made this way, by writing random
bytes into a third node's pty).

The hub run is measured first: the hub's air itself puts N random bytes on air 1.5 ms after the
end of an R1 frame (R2's turn is starting), in the air's own clock. (Writing them into a spare
node when a sniffer heard R1's End put them at an offset known only to the sniffer's few
milliseconds of latency: near R2's start, 5 ms after the End, the two worlds then saw
different scenarios, and the test was flaky.) Every frame is timed in one clock, the hub's air
ticks, from the hub's own capture of what was on air, and the burst starts at the air tick the
hub gave it. The wall clock of a thread of the test process (a sniffer's, or the hub's when it
injects) can be read 100 ms and more late on a loaded 2-core machine (the GIL, the collector),
which would make the gap after the burst look that much shorter; ``inject_late_ms`` in the
failure report says how late the hub's thread ran the injection (the burst's place on air does
not depend on it). The simulator then runs the same ring with the real-time margins the
processes use (``realtime_config``), puts the same bytes on air at the same offset from the end
of an R1 frame, and the two outcomes are compared:

* drops: equal (none);
* missed turns: equal (none: no gap of about Tmax after the burst);
* who owns the first good frame after the burst: equal;
* the longest gap without a good frame (burst start to the next good frame): within 40 ms.
  The hub's air times include the pty and scheduler latency of the child processes (a few
  ms each, tens on a loaded 2-core machine).

A hub run that fails a check and in which a child process, the hub or the host ran more than
20 ms late (``processes.disturbed``: a child's ``stall`` or ``late`` event, the hub's late
timers, the host's worst wake-up) did not run the simulator's scenario with the CPU the
real-time margins assume (a stalled child even resynchronises, which the simulator's run does
not): it is made again, up to ``ATTEMPTS`` runs in all, each listed in the report. A failed
check in an undisturbed run fails at once. A failure prints every packet on the hub's air near
the burst, broken ones too.
"""
from __future__ import annotations

import json
import pprint
import random
import time

import pytest

from firmware_model.radio.deframer import Deframer, FrameReceived
from firmware_model.radio.errors import FrameError
from firmware_model.radio.frame import parse_frame
from firmware_model.radio.mac import MacConfig
from firmware_model.timing import PC_BYTE_TICKS, TMAX_TICKS, s_to_ticks
from hil.bench import scripts as bench
from hil.bench.radio_hub import RadioHub
from hil.bench.runner import realtime_config
from hil.sim.world import SimConfig, World
from hostload import SchedulingLatency
from processes import ATTEMPTS, disturbed, ring_is, spawn, stop, wait_for

TOLERANCE_MS = 40.0
BURSTS = [(13, 1), (120, 2), (300, 3)]       # (bytes, seed): the finding's range, 13-300 bytes


def outcome(frames, t0, n, src_key="src"):
    """(first good frame's source after the burst, gap in ms from burst start to it, missed
    turns after the burst) from frames as (src, start, end) in ticks."""
    t_end = t0 + n * PC_BYTE_TICKS
    after = [f for f in frames if f[1] >= t_end]
    first = after[0]
    misses = sum(1 for a, b in zip(after, after[1:]) if b[1] - a[2] > TMAX_TICKS * 0.95)
    return first[0], (first[1] - t0) / 16_000, misses


OFFSET_TICKS = 24_000
"""The burst starts 1.5 ms after R1's End: inside R2's Ttrans switch (5 ms), so that R2's
frame always runs into it, whatever the processes' few milliseconds of latency."""


class _AirLog:
    """A capture sink for the hub (``RadioHub.capture``): every good frame on the hub's air as
    (src, start, end) in air ticks, deframed per node like a receiver would; and, once armed,
    at the end of R1's next whole frame (node 0) it puts the burst on the hub's air
    ``OFFSET_TICKS`` later, noting that air tick (``t0``).

    Whole: the packet parses as one frame. A frame the hub read from R1's pty in two pieces
    with a gap between them is two packets, the first starting with the Header; firing on it
    would put the burst in the middle of R1's frame instead of R2's hand-over, a different
    scenario. ``split`` counts such packets for the failure report; ``late_ms`` is how late
    the hub's thread ran the injection (it does not move the burst on air)."""

    tsresol = 9
    epoch_units = 0

    def __init__(self, hub, data):
        self.hub, self.data = hub, data
        self.armed = False
        self.t0 = None
        self.late_ms = None
        self.split = 0
        self.frames: list[tuple[int, int, int]] = []
        self.packets: list[tuple[object, int, int, int, str | None]] = []
        """Everything on air, broken or not: (node or "foreign", first byte's start tick,
        last byte's end tick, bytes, the hub's comment)."""
        self._deframers: dict[object, Deframer] = {}

    def follow(self, clock):              # PcapWriter's: stamps stay ticks here
        pass

    def radio(self, key, tick, data, comment=None):
        bt = self.hub.byte_ticks
        self.packets.append((key, tick - (len(data) - 1) * bt, tick, len(data), comment))
        if key == "foreign":                   # the burst itself: no robot's frame
            return
        d = self._deframers.setdefault(key, Deframer(byte_ticks=bt))
        if comment is not None:                # collided or cut: nothing good in it
            d.reset()
        else:
            for ev in d.feed(data, tick - (len(data) - 1) * bt, bt):
                if isinstance(ev, FrameReceived):
                    n = ev.frame.nbytes
                    self.frames.append((ev.frame.src, ev.end - n * bt, ev.end))
        if not (self.armed and key == 0 and comment is None):
            return
        try:
            parse_frame(data)
        except FrameError:
            self.split += 1
            return
        self.armed = False
        self.hub.sched.at(tick + OFFSET_TICKS, self._inject)

    def _inject(self):
        sched = self.hub.sched
        self.t0 = sched.now
        self.late_ms = (sched.wall() - sched.now) / 16_000
        self.hub.air.inject(self.data)


def hub_run(n, seed, logs):
    """The hub run; each child's MAC events (``--events``) go to ``logs``/R<i>.jsonl, for the
    failure report. ``why``: how the run was disturbed (``processes.disturbed``): a child, the
    hub or the host more than 20 ms late."""
    hub = RadioHub(nodes=4, seed=1)
    outs = [open(logs / f"R{i}.jsonl", "w") for i in (1, 2)]
    kids = [spawn("child", "--id", str(i), "--radio", hub.paths[i - 1], "--team", "1,2",
                  "--events", stdout=outs[i - 1]) for i in (1, 2)]
    sniffer = bench.Sniffer(hub.paths[3]).start()
    air = _AirLog(hub, random.Random(seed).randbytes(n))
    hub.capture(air)
    hub.start()
    probe = SchedulingLatency().__enter__()
    try:
        assert wait_for(lambda: ring_is(sniffer, [1, 2]), 40.0), "the ring did not form"
        air.armed = True                              # a foreign transmitter, on the air
        assert wait_for(lambda: air.t0 is not None, 5.0)
        time.sleep(n / 960 + 3.0)
        alive = {p.poll() is None for p in kids}
    finally:
        sniffer.stop()
        stop(kids)
        for f in outs:
            f.close()
        probe.stop()
        hub_lates = list(hub.sched.lates) if hub.sched is not None else []
        hub.stop()
        hub.close()
    assert alive == {True}
    events = [list(map(json.loads, (logs / f"R{i}.jsonl").read_text().splitlines()))
              for i in (1, 2)]
    why = disturbed(events, hub_lates, probe)
    return list(air.frames), air.t0, air.split, air.late_ms, list(air.packets), why


def sim_run(offset_ticks, n, seed):
    evs: list[dict] = []
    cfg = realtime_config(MacConfig(team=frozenset((1, 2))))
    w = World(SimConfig(robots=(1, 2), duration=20.0, mac=cfg), on_event=evs.append)
    w.run(s_to_ticks(8.0))
    while not [e for e in evs if e["ev"] == "frame" and e["src"] == 1 and
               e["end"] > s_to_ticks(8.0)]:
        w.run(w.now + 1000)
    e1 = [e for e in evs if e["ev"] == "frame" and e["src"] == 1][-1]["end"]
    t0 = max(w.now, e1 + offset_ticks)
    w.inject_bytes(random.Random(seed).randbytes(n), t0)
    w.run(t0 + s_to_ticks(3.0))
    frames = [(e["src"], e["start"], e["end"]) for e in evs
              if e["ev"] == "frame" and not e["collided"] and e["start"] >= t0]
    drops = [e for e in evs if e["ev"] == "disable"]
    return frames, t0, drops


@pytest.mark.timing
@pytest.mark.parametrize("n, seed", BURSTS, ids=[f"{n}B" for n, _ in BURSTS])
def test_simulator_and_hub_agree_on_a_foreign_burst_over_a_handover(n, seed, tmp_path):
    sframes, st0, drops = sim_run(OFFSET_TICKS, n, seed)
    sim_src, sim_gap, sim_misses = outcome(sframes, st0, n)
    runs = []
    for attempt in range(1, ATTEMPTS + 1):
        logs = tmp_path / f"attempt{attempt}"
        logs.mkdir()
        failed, why, report = _compare(n, seed, logs, sframes, st0, drops,
                                       (sim_src, sim_gap, sim_misses))
        if not failed:
            return
        runs.append((attempt, failed, why))
        if not why:
            break
    pytest.fail(f"{'; '.join(failed)}:\n{pprint.pformat(report, width=100)}\n"
                f"runs: {pprint.pformat(runs, width=100)}")


def _compare(n, seed, logs, sframes, st0, drops, sim):
    """One hub run against the simulator's outcome ``sim``: (the checks that failed, how the
    run was disturbed, the report)."""
    hframes, ht0, split, late_ms, packets, why = hub_run(n, seed, logs)
    hub_src, hub_gap, hub_misses = outcome(hframes, ht0, n)
    sim_src, sim_gap, sim_misses = sim

    def near(fs, t0):
        return [(f[0], round((f[1] - t0) / 16_000, 1), round((f[2] - t0) / 16_000, 1))
                for f in fs if -40 * 16_000 < f[1] - t0 < (n + 300) * 16_000]
    # in ms from the burst's start: the good frames of both worlds; everything on the hub's air
    # (the broken and foreign packets too: when robot 2 began, whether it collided); R1's
    # packets that were not a whole frame (_AirLog)
    report = dict(offset_ms=OFFSET_TICKS / 16_000, split_packets=split, inject_late_ms=late_ms,
                  children_mac_events=str(logs), disturbed=why,
                  hub=(hub_src, hub_gap, hub_misses),
                  sim=(sim_src, sim_gap, sim_misses), hub_frames=near(hframes, ht0),
                  sim_frames=near(sframes, st0),
                  hub_air=[(k, round((a - ht0) / 16_000, 1), round((b - ht0) / 16_000, 1), nb, c)
                           for k, a, b, nb, c in packets
                           if -40 * 16_000 < a - ht0 < (n + 300) * 16_000])
    checks = {
        "nobody dropped, both robots on air after the burst":
            not drops and {f[0] for f in hframes if f[1] > ht0 + s_to_ticks(1.5)} == {1, 2},
        "no missed turn in either world": hub_misses == sim_misses == 0,
        "the same robot owns the first good frame": hub_src == sim_src,
        f"the gaps agree within {TOLERANCE_MS} ms": abs(hub_gap - sim_gap) <= TOLERANCE_MS,
    }
    # (pytest.fail prints the whole report, not an assertion's abbreviated repr)
    return [name for name, ok in checks.items() if not ok], why, report
