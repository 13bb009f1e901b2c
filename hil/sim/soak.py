"""Soak: hours of simulated time with random faults and traffic, ending with the invariants.

``rprs soak --hours H --seed S`` runs a ring (the father with a standby PC, and children with
their CAN side) under seeded random faults of every kind (hil.sim.faults) spaced about a minute
apart, with traffic, then lets the queues drain and checks the guarantees of docs/guarantees.md:

* every submitted message ended delivered or failed with a reason (after the drain nothing is
  pending), within ``max_age`` (60 s) of its submission and the next frame heard;
* no message was delivered twice, or to a robot it was not for;
* no robot acted on a corrupted command (with the checksum extension; without it the count is
  what the paper's frame lets through);
* after every fault the ring re-formed (every robot whose radio works is in everyone's ring)
  within the documented bound.
"""
from __future__ import annotations

import math
import multiprocessing
import multiprocessing.connection
import os
import random
import signal
import time
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING

from firmware_model.radio.mac import MacConfig
from firmware_model.timing import TICK_HZ, s_to_ticks

from .faults import NODES, Fault
from .quiet_can import PERIOD
from .world import SimConfig, World

if TYPE_CHECKING:
    from firmware_model.cycle_costs import CycleCosts

    from .trace import TraceWriter

REFORM_BOUND_S = 15.0
"""Documented bound (docs/guarantees.md): the ring is whole again within this long after the
last fault ends. Start-up claim |team| x Tmax (4.2 s for 7) + invitations (P x gap cycles)."""

SETTLE_S = 10.0
"""Simulated seconds from the start before the first fault: the ring forms."""
DRAIN_S = 120.0
"""Simulated seconds at the end with no new fault (and, 10 s later, no new traffic): the
queues drain and the ring re-forms before the invariants are read."""
MIN_HOURS = 0.05
"""The shortest soak (180 s): shorter ones would end their fault window and their traffic
before either began, and pass having tested nothing."""

SAMPLE_S = 0.25
MAX_AGE_S = 60.0
"""The soak's ``max_age``: every message ends delivered or failed within it (guarantees.md)."""
AGE_SLACK_S = 2.0
"""What a message may take past ``max_age``: a station that takes no turns fails it on the
next frame it hears (a live ring's come within Tmax; a stall-gap's closing ends the turn)."""


def random_faults(rng: random.Random, robots: tuple[int, ...], hours: float, can: bool,
                  standby: bool, mean_gap_s: float = 60.0) -> list[Fault]:
    """A seeded schedule of faults of every kind, about ``mean_gap_s`` apart, at least one
    (a short soak's window, 50 s at :data:`MIN_HOURS`, drew none for 47 seeds of 100, and
    passed having tested nothing: its one fault then comes anywhere in the window)."""
    children = [r for r in robots if r != 0]
    kinds = ["fail", "steal", "ber", "noise", "burst", "drop"]
    if can and children:
        kinds += ["busoff", "stuck", "silent", "stall"]
    if standby and 0 in robots:
        kinds.append("father")
    end = hours * 3600.0 - DRAIN_S
    out: list[Fault] = []
    t = SETTLE_S
    while True:
        t += rng.expovariate(1.0 / mean_gap_s)
        if t >= end:
            if out or end <= SETTLE_S:
                break
            t = rng.uniform(SETTLE_S, end)
            end = t            # (this one, then no more)
        k = rng.choice(kinds)
        d = rng.uniform(1.0, 15.0)
        if k == "fail":
            r = rng.choice(children or list(robots))
            out += [Fault("fail", r, t), Fault("recover", r, t + d)]
        elif k == "father":
            out += [Fault("fail", 0, t), Fault("recover", 0, t + d)]
        elif k == "steal":
            out.append(Fault("steal", rng.choice(list(robots)), t))
        elif k == "ber":
            out.append(Fault("ber", None, t, t + d, round(rng.uniform(1e-3, 1e-2), 4)))
        elif k == "noise":
            out.append(Fault("noise", None, t, t + d))
        elif k == "burst":
            out.append(Fault("burst", None, t, None, round(rng.uniform(0.02, 0.5), 3)))
        elif k == "drop":
            out.append(Fault("drop", None, t, t + d, round(rng.uniform(1e-3, 5e-3), 4)))
        elif k == "busoff":
            out.append(Fault("busoff", rng.choice(children), t))
        elif k == "stuck":
            out.append(Fault("stuck", rng.choice(children), t, t + rng.uniform(0.2, 3.0)))
        elif k == "silent":
            out.append(Fault("silent", rng.choice(children), t, t + d, None, rng.choice(NODES)))
        elif k == "stall":
            node = rng.choice([n for n in NODES if n != "PAW"])
            out.append(Fault("stall", rng.choice(children), t, t + d, None, node))
    return out


@dataclass
class SoakResult:
    hours: float
    seed: int
    checksum: bool
    faults: dict[str, int]
    summary: dict
    reform_s: list[float] = field(default_factory=list)
    not_reformed: int = 0
    wall_s: float = 0.0
    isolations: int = 0
    bus_offs: int = 0
    unexplained_drops: list[tuple[float, int]] = field(default_factory=list)
    """(s, robot) of each drop that no radio fault explains (:func:`unexplained_drops`)."""
    can_periods_skipped: float = 0.0
    """Share of the children's CAN status periods that slept instead of running frame by
    frame (hil/sim/quiet_can.py; how the run was computed, not what it found)."""

    @property
    def invariants(self) -> dict[str, bool]:
        s = self.summary
        return {
            "every message delivered or failed": s["pending"] == 0 and
            s["submitted"] == s["delivered"] + s["failed"],
            f"every message ended within {MAX_AGE_S:g} s (+ {AGE_SLACK_S:g})":
                s["oldest_outcome_s"] <= MAX_AGE_S + AGE_SLACK_S,
            "nothing delivered twice": s["duplicate_deliveries"] == 0,
            "nothing delivered to the wrong robot": s["wrong_robot_deliveries"] == 0,
            "no corrupted command acted on": s["corrupt_deliveries"] == 0,
            f"ring re-formed within {REFORM_BOUND_S:g} s of every fault":
                self.not_reformed == 0 and all(x <= REFORM_BOUND_S for x in self.reform_s),
            f"no robot dropped but in a radio fault (+ {REFORM_BOUND_S:g} s)":
                not self.unexplained_drops,
        }

    CHECKSUM_ONLY = ("nothing delivered twice", "no corrupted command acted on")
    """Invariants promised only with the checksum (docs/guarantees.md): the paper's frame lets
    a byte error in a command or a retransmission's Number through."""

    @property
    def kept(self) -> bool:
        """Every invariant this run promises held: all of them with the checksum, all but
        :attr:`CHECKSUM_ONLY` without it."""
        return all(ok for name, ok in self.invariants.items()
                   if self.checksum or name not in self.CHECKSUM_ONLY)


RADIO_FAULTS = frozenset({"fail", "recover", "steal", "ber", "noise", "burst", "drop",
                          "foreign", "skew"})
"""Faults on the radio side: only these may cost a robot its place in the ring (a CAN fault
stays inside its child, docs/guarantees.md)."""


def unexplained_drops(membership: list[tuple[int, str, int]], faults: list[Fault]
                      ) -> list[tuple[float, int]]:
    """(s, robot) of each drop (``disable``, World.membership) after the ring first formed
    (:data:`SETTLE_S`) that no radio fault explains: none acting then or ended within
    :data:`REFORM_BOUND_S` before (a skew acts all the run). A ring that re-formed must stay
    whole until the next fault; a healthy robot dropped then was counted missing."""
    windows = [(f.at, math.inf if f.kind == "skew" else f.end + REFORM_BOUND_S)
               for f in faults if f.kind in RADIO_FAULTS]
    out = []
    for tick, kind, robot in membership:
        t = tick / TICK_HZ
        if kind == "disable" and t >= SETTLE_S and not any(a <= t <= e for a, e in windows):
            out.append((round(t, 3), robot))
    return out


def run_timing_reformations(w: World, faults, progress=None) -> tuple[list[float], int]:
    """Run ``w`` to its end in steps of SAMPLE_S; after each fault ends with no other active,
    time how long until the ring is whole again (``World.ring_complete``), from the last
    fault's end when others began meanwhile (the promise is about the ring after the faults,
    not under them). Returns those
    times (s, to SAMPLE_S) and how many re-formations did not happen (within 4 x the bound,
    or by the end). While no re-formation is being timed, the steps go in one run to the step
    at which the next fault's end is seen: the same samples, and room for an idle ring to leap
    over its cycles (hil/sim/quiet_ring.py), which a step bounds. ``progress(simulated_s)``
    is called after each run, at least every hundredth of the soak (a run stops there)."""
    ends = sorted({round(f.end, 6) for f in faults if f.kind != "skew"})
    starts = [(f.at, f.end) for f in faults]
    reform: list[float] = []
    not_reformed = 0
    pending_end: float | None = None
    step = s_to_ticks(SAMPLE_S)
    shown = max(1, w.end_tick // 100 // step) * step      # ticks between progress calls
    i = 0
    while w.now < w.end_tick:
        until = w.now + step
        if pending_end is None:
            until = _step_seeing(w.now, step, ends[i] if i < len(ends) else None, w.end_tick)
            if progress is not None:
                until = min(until, w.now + shown)
        w._advance(until)                        # the ring check reads the radio side only
        now_s = w.now / TICK_HZ
        while i < len(ends) and ends[i] <= now_s:
            # a fault just ended; if nothing else is active, time the re-formation
            active = any(a <= now_s < e for a, e in starts)
            if not active:
                pending_end = ends[i] if pending_end is None else pending_end
            i += 1
        if pending_end is not None and any(pending_end < a <= now_s for a, _ in starts):
            # a fault began before the ring re-formed: the time runs from the last end
            active = any(a <= now_s < e for a, e in starts)
            pending_end = None if active else max(e for _, e in starts if e <= now_s)
        if pending_end is not None:
            if w.ring_complete():
                reform.append(round(now_s - pending_end, 3))
                pending_end = None
            elif now_s - pending_end > 4 * REFORM_BOUND_S:
                not_reformed += 1
                pending_end = None
        if progress is not None:
            progress(now_s)
    if pending_end is not None and not w.ring_complete():
        not_reformed += 1
    return reform, not_reformed


def _step_seeing(now: int, step: int, end_s: float | None, last: int) -> int:
    """The first tick of the grid ``now + m * step`` (m >= 1) at which ``end_s <= tick /
    TICK_HZ``, as the step-by-step loop compares it (``last`` if none comes first)."""
    if end_s is None:
        return last
    m = max(1, math.ceil((end_s * TICK_HZ - now) / step))
    while m > 1 and end_s <= (now + (m - 1) * step) / TICK_HZ:
        m -= 1
    while not end_s <= (now + m * step) / TICK_HZ:
        m += 1
    return min(now + m * step, last)


def run_soak(hours: float, seed: int, robots: tuple[int, ...] = (0, 1, 2, 3, 4),
             checksum: bool = True, can: bool = True, load: float = 0.5,
             progress=None, faults: list[Fault] | None = None,
             can_sleep: bool = True, cpu: CycleCosts | None = None,
             trace: TraceWriter | None = None) -> SoakResult:
    """Run the soak; ``progress(simulated_s)`` is called as it goes. ``can_sleep``: see
    SimConfig (the result is the same either way); ``cpu``: the children's cycle costs (None:
    the ideal CPU; ``rprs soak`` gives the CPU model unless ``--cpu ideal``); ``trace``: the
    run's events are written there (docs/trace.md), its meta line carrying the configuration.
    ``hours`` below :data:`MIN_HOURS`: a ValueError."""
    if not hours >= MIN_HOURS:
        raise ValueError(f"a soak lasts at least {MIN_HOURS:g} h ({MIN_HOURS * 3600:g} s): "
                         f"faults begin {SETTLE_S:g} s in and stop {DRAIN_S:g} s before the "
                         f"end, so a shorter one would test nothing (asked {hours:g} h)")
    rng = random.Random(f"{seed}:soak")
    standby = 0 in robots
    if faults is None:
        faults = random_faults(rng, robots, hours, can, standby)
    duration = hours * 3600.0
    cfg = SimConfig(robots=robots, duration=duration, seed=seed, load=load,
                    load_until=duration - DRAIN_S + SETTLE_S, can=can, can_sleep=can_sleep,
                    father_standby=standby, cpu=cpu,
                    faults=tuple(faults), mac=MacConfig(checksum=checksum,
                                                        max_age=s_to_ticks(MAX_AGE_S)))
    t0 = time.perf_counter()
    w = World(cfg, trace)
    reform, not_reformed = run_timing_reformations(w, faults, progress)
    w.wake_can()
    counts: dict[str, int] = {}
    for f in faults:
        counts[f.kind] = counts.get(f.kind, 0) + 1
    res = SoakResult(hours, seed, checksum, counts, w.summary(), reform, not_reformed,
                     time.perf_counter() - t0)
    res.unexplained_drops = unexplained_drops(w.membership, faults)
    res.isolations = sum(c.can.isolations for c in w.children.values())
    res.bus_offs = sum(c.can.bus_offs for c in w.children.values())
    if w.quiet:
        periods = len(w.quiet) * (w.end_tick // PERIOD)
        res.can_periods_skipped = sum(q.periods_skipped for q in w.quiet.values()) / periods
    return res


STOP_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP")
                     if hasattr(signal, n))
"""The signals that stop a soak (Ctrl-C, ``kill``, its terminal closed), held while its
processes fork."""


def run_soaks(hours: float, seed: int, checksums: list[bool], parallel: bool | None = None,
              progress=None, **kw) -> list[SoakResult]:
    """:func:`run_soak` once per checksum setting (the paper's frame against the extension,
    same seed), in that order. ``parallel`` (default: with two runs and two CPUs or more):
    each run in a process of its own at the same time; the results are the same as one
    after the other, only the wall time differs. ``progress(i, simulated_s)`` is called for
    run ``i`` as it goes."""
    if parallel is None:
        cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else \
            (os.cpu_count() or 1)                  # the CPUs this process may use
        parallel = len(checksums) > 1 and cpus > 1
    if not parallel:
        return [run_soak(hours, seed, checksum=ck, progress=None if progress is None else
                         partial(progress, i), **kw) for i, ck in enumerate(checksums)]
    ctx = multiprocessing.get_context("fork")
    done = [ctx.Value("d", 0.0, lock=False) for _ in checksums]
    pipes = [ctx.Pipe(duplex=False) for _ in checksums]         # (parent's end, child's)
    procs = [ctx.Process(target=_soak_child, args=(pipes[i][1], done[i], hours, seed, ck, kw),
                         daemon=True) for i, ck in enumerate(checksums)]
    results: dict[int, SoakResult] = {}
    try:
        # Ctrl-C, SIGTERM and SIGHUP wait while the processes fork: a child they reached before its
        # own handlers were set ran the parent's, and printed a traceback from the middle of
        # the fork ("Exception ignored in: <function _after_fork>"). Each child unblocks them
        # once its handlers are its own; the parent here, after the last fork.
        held = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            for p in procs:
                p.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
        for _, child_end in pipes:
            child_end.close()
        waiting = {parent_end: i for i, (parent_end, _) in enumerate(pipes)}
        while waiting:
            for conn in multiprocessing.connection.wait(list(waiting), timeout=0.1):
                # (wait hands back the pipe ends it was given)
                assert isinstance(conn, multiprocessing.connection.Connection)
                i = waiting.pop(conn)
                try:
                    res = conn.recv()
                except EOFError:
                    procs[i].join()
                    raise RuntimeError(f"the soak process with checksum "
                                       f"{'on' if checksums[i] else 'off'} died without a "
                                       f"result (exit status {procs[i].exitcode})") from None
                if isinstance(res, BaseException):
                    raise res
                results[i] = res
            if progress is not None:
                for i, v in enumerate(done):
                    progress(i, v.value)
    finally:                              # Ctrl-C or a failure: no soak is left running
        for p in procs:
            if p.is_alive():
                p.terminate()
            if p.pid is not None:
                p.join()
        for parent_end, _ in pipes:
            parent_end.close()
    return [results[i] for i in range(len(procs))]


def _soak_child(conn, done, hours: float, seed: int, checksum: bool, kw: dict) -> None:
    """One run of :func:`run_soaks` in its own process: its result (or its error) goes back
    through ``conn``, its simulated seconds into ``done``. Ctrl-C is the parent's to handle
    (it stops this process: SIGTERM ends it at once, whatever handler the parent had), and
    so is a closed terminal's SIGHUP."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "SIGHUP"):
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)   # (held by the parent's fork)

    def progress(s: float) -> None:
        done.value = s
    try:
        res: object = run_soak(hours, seed, checksum=checksum, progress=progress, **kw)
    except Exception as exc:              # noqa: BLE001 - handed to the parent, which raises it
        res = exc
    conn.send(res)
    conn.close()


def report(results: list[SoakResult]) -> str:
    """A Markdown table: one column per run (e.g. with and without the checksum)."""
    head = "| | " + " | ".join(f"checksum {'on' if r.checksum else 'off'}"
                                for r in results) + " |"
    rows = [head, "|---|" + "---|" * len(results)]

    def row(name: str, vals) -> None:
        rows.append(f"| {name} | " + " | ".join(str(v) for v in vals) + " |")
    row("simulated hours", [f"{r.hours:g}" for r in results])
    row("wall seconds", [f"{r.wall_s:.0f}" for r in results])
    row("faults injected", [sum(v for k, v in r.faults.items() if k != "recover")
                            for r in results])
    kinds = sorted({k for r in results for k in r.faults if k != "recover"})
    for k in kinds:
        row(f"  {k}", [r.faults.get(k, 0) for r in results])
    s = [r.summary for r in results]
    row("frames on air", [x["occupations"] for x in s])
    row("collisions", [x["collisions"] for x in s])
    row("turns missed", [sum(v["missed"] for v in x["robots"].values()) for x in s])
    row("ring membership changes", [len(x["membership_changes"]) for x in s])
    row("messages submitted", [x["submitted"] for x in s])
    row("delivered", [x["delivered"] for x in s])
    row("failed (with a reason)", [x["failed"] for x in s])
    row("pending at the end", [x["pending"] for x in s])
    row("oldest message at its end (s)", [x["oldest_outcome_s"] for x in s])
    row("delivered twice", [x["duplicate_deliveries"] for x in s])
    row("delivered to the wrong robot", [x["wrong_robot_deliveries"] for x in s])
    row("corrupted commands acted on", [x["corrupt_deliveries"] for x in s])
    row("frames refused (spoofing/bounds)",
        [sum(v["refused_frames"] for v in x["robots"].values()) for x in s])
    row("ring re-formations timed", [len(r.reform_s) for r in results])
    row("longest re-formation (s)", [max(r.reform_s) if r.reform_s else "-" for r in results])
    row("robots dropped with no radio fault", [len(r.unexplained_drops) for r in results])
    row("CAN bus-offs / isolations", [f"{r.bus_offs} / {r.isolations}" for r in results])
    for name in results[0].invariants:
        row(f"**{name}**", [_verdict(r, name) for r in results])
    row("**every promise kept**", ["yes" if r.kept else "**NO**" for r in results])
    if any(not r.checksum for r in results) and \
            any(_verdict(r, n) != "yes" for r in results for n in r.invariants):
        # the notation's legend, where a no is shown (every promise kept: nothing to read)
        rows += ["", "Key: a bold **NO** would mark a broken promise (exit status 1). "
                 "Without the checksum " + " and ".join(f"'{n}'" for n in
                                                       SoakResult.CHECKSUM_ONLY)
                 + " are not promised (docs/guarantees.md: the paper's frame lets a byte "
                 "error through): a no there is expected and leaves the exit status 0."]
    return "\n".join(rows)


def _verdict(r: SoakResult, name: str) -> str:
    """One invariant's cell: yes, a broken promise (**NO**), or a no that is not one (an
    invariant promised only with the checksum, in a run without it)."""
    if r.invariants[name]:
        return "yes"
    if not r.checksum and name in SoakResult.CHECKSUM_ONLY:
        return "no (not promised without the checksum)"
    return "**NO**"
