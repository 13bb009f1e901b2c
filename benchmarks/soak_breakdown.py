"""Where the soak's time goes, event by event, and how long its jobs last.

    python benchmarks/soak_breakdown.py [--hours 0.1] [--seed 11]

Runs ``run_soak(hours, seed)`` (hil/sim/soak.py) once, timing every event the world's
scheduler runs (``time.process_time``, so a busy machine inflates the total less than the
wall clock) and charging it to what ran it:

* ``radio and world``: the radio side (air, stations, MACs), faults, the world's bookkeeping,
  and the children's answers to what the radio brings (which may start a job);
* ``CAN, job and a moving node``: a child's CAN-side event while its dispatcher has a job and
  a submodule moves (not a cruising wheel);
* ``CAN, job only`` / ``CAN, moving only`` / ``CAN, neither``: the other awake CAN periods
  (``neither``: after a job, until the domain falls asleep);
* ``probes``: the CAN domains' probes (snapshots and their comparisons,
  hil/sim/quiet_can.py);
* ``wakes`` (inside ``radio and world``, shown apart): a sleeping CAN side brought up to the
  tick now (whole periods added up, the last partial period and perhaps the last whole one
  run frame by frame).

It also records every joint job (``Dispatcher._drive_joints``: every move order) from its
start to its done, in CAN periods (100 ms): a domain that slept through a job would pay two
snapshots and a replayed period for each sleep, so only jobs much longer than that could gain.

Figures and what they decided: docs/performance.md (where the soak's time goes). The instrumented
run is
about twice as slow as a plain one; the shares are what counts.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import heapq
import os
import statistics
import sys
import time
from collections import Counter

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from can_bus.dbc import STATE_MOVING  # noqa: E402
from firmware_model import dispatcher as dispatcher_module  # noqa: E402
from firmware_model.mcu.scheduler import Scheduler  # noqa: E402
from hil.sim import world as world_module  # noqa: E402
from hil.sim.quiet_can import PERIOD, QuietCan  # noqa: E402
from hil.sim.soak import run_soak  # noqa: E402

CATEGORIES = ("radio and world", "CAN, job and a moving node", "CAN, job only",
              "CAN, moving only", "CAN, neither", "probes")


class Breakdown:
    """The instrumented soak: ``seconds`` and ``events`` by category, ``wakes`` (s, count),
    ``jobs`` (each joint job done: its length in CAN periods), ``superseded`` (each joint job
    a newer command replaced: its length until then) and ``open_jobs`` (failed or still
    running at the end)."""

    def __init__(self) -> None:
        self.seconds: Counter = Counter()
        self.events: Counter = Counter()
        self.wake_s = 0.0
        self.wakes = 0
        self.jobs: list[float] = []
        self.superseded: list[float] = []
        self.open_jobs = 0
        self.total_s = 0.0
        self.result = None
        """The soak's SoakResult: the instruments change nothing of the run."""


def measure(hours: float, seed: int) -> Breakdown:
    """Run the soak once under the instruments (restored afterwards)."""
    out = Breakdown()
    worlds: list = []
    clock = time.process_time
    D = dispatcher_module.Dispatcher
    saved = (world_module.World.__init__, Scheduler.run_until, QuietCan.wake,
             D._drive_joints, D._job_done, D._next_seq)
    init, run_until, wake, drive, done, next_seq = saved
    started: dict[int, tuple[int, object]] = {}   # id -> (start, the job: kept alive, so
    # that no later job, a wheel's or the paw's, takes its id)

    def world_init(self, *a, **k):
        init(self, *a, **k)
        worlds.append(self)

    def timed_run_until(self, end: int) -> None:
        w = worlds[0] if worlds else None
        if w is None or self is not w.sched:       # a waking domain's private scheduler:
            return run_until(self, end)            # charged to the wake
        owners = {id(q): r for r, q in w.quiet.items()}
        heap = self._heap
        while heap and heap[0][0] <= end:
            when, _, ev = heapq.heappop(heap)
            if ev.cancelled:
                continue
            self.now = when
            t = clock()
            ev.fn(*ev.args)
            dt = clock() - t
            owner = ev.owner
            if getattr(ev.fn, "__func__", None) is QuietCan._probe:
                cat = "probes"
            elif owner is not None and id(owner) in owners:
                r = owners[id(owner)]
                job = bool(w.children[r].dispatcher.jobs)
                moving = any(n.state == STATE_MOVING and not n.cruising
                             for n in w.submodules[r].values())
                cat = ("CAN, job and a moving node" if job and moving else "CAN, job only"
                       if job else "CAN, moving only" if moving else "CAN, neither")
            else:
                cat = "radio and world"
            out.seconds[cat] += dt
            out.events[cat] += 1
        if end > self.now:
            self.now = end

    def timed_wake(self, work: bool = False) -> None:
        if not self.asleep:
            return
        t = clock()
        wake(self, work)
        out.wake_s += clock() - t
        out.wakes += 1

    def drive_joints(self, src, c, now, q, only=None):
        job = drive(self, src, c, now, q, only)
        if job is not None:
            started[id(job)] = (now, job)
        return job

    def job_done(self, job, now):
        entry = started.pop(id(job), None)
        if entry is not None:
            out.jobs.append((now - entry[0]) / PERIOD)
        done(self, job, now)

    def superseding(self, n):
        before = list(self.jobs)
        seq = next_seq(self, n)              # drops the jobs a new command supersedes
        for job in before:
            if job not in self.jobs:
                entry = started.pop(id(job), None)
                if entry is not None:
                    out.superseded.append((worlds[0].sched.now - entry[0]) / PERIOD)
        return seq

    world_module.World.__init__ = world_init
    Scheduler.run_until = timed_run_until
    QuietCan.wake = timed_wake
    D._drive_joints, D._job_done, D._next_seq = drive_joints, job_done, superseding
    try:
        t = clock()
        out.result = run_soak(hours, seed)
        out.total_s = clock() - t
    finally:
        (world_module.World.__init__, Scheduler.run_until, QuietCan.wake,
         D._drive_joints, D._job_done, D._next_seq) = saved
    out.open_jobs = len(started)
    return out


def report(b: Breakdown, hours: float, seed: int) -> str:
    lines = [f"run_soak({hours:g} h, seed {seed}), instrumented: {b.total_s:.2f} CPU s", "",
             "| what ran | CPU s | share | events |", "|---|---|---|---|"]
    for cat in CATEGORIES:
        lines.append(f"| {cat} | {b.seconds[cat]:.2f} | {100 * b.seconds[cat] / b.total_s:.1f} % "
                     f"| {b.events[cat]:,} |")
    lines.append(f"| (wakes, inside radio and world) | {b.wake_s:.2f} | "
                 f"{100 * b.wake_s / b.total_s:.1f} % | {b.wakes:,} |")
    jobs = sorted(b.jobs)
    lines.append("")
    if jobs:
        q = statistics.quantiles(jobs, n=20) if len(jobs) > 1 else [jobs[0]] * 19
        lines.append(f"joint jobs done: {len(jobs):,} (failed or running at the "
                     f"end: {b.open_jobs:,}); length in CAN periods: median "
                     f"{statistics.median(jobs):.1f}, p75 {q[14]:.1f}, p90 {q[17]:.1f}, "
                     f"max {jobs[-1]:.1f}; {sum(jobs):,.0f} periods in all, "
                     f"{sum(max(0.0, x - 4) for x in jobs):,.0f} of them after a job's "
                     f"fourth period")
    else:
        lines.append(f"joint jobs done: 0 (open: {b.open_jobs})")
    sup = b.superseded
    if sup:
        lines.append(f"joint jobs superseded by a newer command: {len(sup):,}; length until "
                     f"then in CAN periods: median {statistics.median(sup):.1f}, max "
                     f"{max(sup):.1f}; {sum(sup):,.0f} periods in all")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=0.1, help="soak length (default 0.1)")
    ap.add_argument("--seed", type=int, default=11, help="soak seed (default 11)")
    a = ap.parse_args(argv)
    print(report(measure(a.hours, a.seed), a.hours, a.seed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
