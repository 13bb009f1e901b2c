"""Random hunt for a fast path that is not the frame-by-frame run: sleeping CAN sides
(hil/sim/quiet_can.py) and ring leaps (hil/sim/quiet_ring.py) against the same world with both
off, on random rings, faults, loads, byte errors and run segments.

    python scripts/sleep_hunt.py [--seed 0] [--runs 100] [--cpu [--cpu-costs FILE]]

Each run draws a world from its seed (robots, duration, CAN sides, the standby father, the
soak's random faults at a random spacing, a load that may stop half-way, byte errors, the
checksum, perhaps a robot gone for good), runs it once with every frame run and once with the
fast paths, the second cut into 0-3 ``World.run`` segments that wake the CAN sides or not, and
compares the summaries and the whole state (every part, every pending event, the random
generators), and the world's events and summary with its receptions in bursts against every
byte at its tick (``byte_by_byte``). A difference prints the world and makes the exit status
1. Two inexact sleeps were
found this way (a message noted between a probe's two snapshots, a cruising wheel whose
odometer did not change for three periods); tests/hil/sim/test_quiet_can.py keeps both as named
scenarios and runs a few seeds of this hunt. With ``--cpu`` each world runs on the CPU
model, its fast paths (lone handlers, bytes late on an idle CPU) against every byte at its
tick on the general path: events, summary, every handler's figures and the state but for
the CPUs and the fast paths' own forms; and, untraced, its
sleeping CAN sides (their interrupts raised as ghosts) against CAN sides that never sleep:
summary, state and every handler's figures.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    import _needs_project  # noqa: F401    (scripts/ is sys.path[0] here)

import argparse
import json
import random
import sys
import time
from dataclasses import replace

from firmware_model.radio.mac import MacConfig
from hil.sim.faults import Fault
from hil.sim.soak import random_faults
from hil.sim.state_walk import portable, snapshot
from hil.sim.world import SimConfig, World

TICK_HZ = 16_000_000


def random_world(seed: int, durations: tuple[int, ...] = (30, 60, 90, 150)
                 ) -> tuple[SimConfig, list[tuple[int, bool]], bool]:
    """A random world, the segments to cut its fast run into (tick, wake the CAN sides), and
    whether both runs record their events (a trace: the ring's leaps write the events of the
    cycles they leap over, and the CAN sides stay awake)."""
    rng = random.Random(seed)
    robots = tuple(sorted(rng.sample(range(7), rng.randint(2, 7))))
    duration = rng.choice(durations)
    can = rng.random() < 0.8
    standby = 0 in robots and rng.random() < 0.3
    faults = random_faults(rng, robots, duration / 3600 + 0.04, can, standby,
                           mean_gap_s=rng.choice([10, 20, 40]))
    if rng.random() < 0.3:                 # a robot gone for good (the soak's come back)
        faults.append(Fault("fail", rng.choice(robots), round(rng.uniform(1, duration), 3)))
    load = rng.choice(["idle", "idle", 0.2, 0.5, 1])
    cfg = SimConfig(robots=robots, duration=duration, seed=rng.randrange(10 ** 6), can=can,
                    load=load, load_until=None if load == "idle" else
                    rng.choice([None, duration / 2]), father_standby=standby,
                    faults=tuple(f for f in faults if f.at < duration),
                    ber=rng.choice([0, 0, 1e-4, 1e-3]),
                    mac=MacConfig(checksum=rng.random() < 0.7))
    cuts = sorted(rng.uniform(0, duration) for _ in range(rng.randint(0, 3)))
    return cfg, [(round(c * TICK_HZ), rng.random() < 0.5) for c in cuts], rng.random() < 0.3


def state(w: World) -> list:
    """The whole world as a comparable list (CAN sides woken first)."""
    w.wake_can()
    parts = [p for _, q in sorted(w.quiet.items()) for p in q.roots]
    stations = [w.stations[r] for r in sorted(w.stations)]
    boundary = [w.sched, *w.quiet.values(), *(q.clock for q in w.quiet.values())]
    return portable(snapshot([*parts, stations, w.air], boundary, rng_state=True))


def summary(w: World) -> str:
    return json.dumps(w.summary(), sort_keys=True, default=str)


def same_run(cfg: SimConfig, cuts: list[tuple[int, bool]], traced: bool = False) -> bool:
    """Does the fast run, cut at ``cuts``, end exactly where the frame-by-frame run does (and,
    ``traced``, write the same events)?"""
    slow_events: list[dict] = []
    fast_events: list[dict] = []
    slow = World(replace(cfg, can_sleep=False, ring_sleep=False),
                 on_event=slow_events.append if traced else None)
    slow.run()
    fast = World(cfg, on_event=fast_events.append if traced else None)
    for tick, wake in cuts:
        (fast.run if wake else fast._advance)(tick)
    fast.run()
    return (summary(fast) == summary(slow) and state(fast) == state(slow)
            and fast_events == slow_events)


def same_bytewise_run(cfg: SimConfig) -> bool:
    """Does the run give the events and summary of the run with every byte at its tick
    (``byte_by_byte``: no burst delivery, docs/fast-paths.md "Clean receptions in one
    burst")?"""
    runs = []
    for bb in (False, True):
        events: list[dict] = []
        w = World(replace(cfg, byte_by_byte=bb), on_event=events.append)
        w.run()
        runs.append((summary(w), events))
    return runs[0] == runs[1]


def cpu_figures(w: World) -> dict:
    """Every child's CPU figures on the CPU model: busy cycles and each handler's calls, busy
    cycles, latency and response counts."""
    return {r: (c.busy, sorted((s.name, s.calls, s.busy, sorted(s.latency.items()),
                                sorted(s.response.items()), s.worst_latency, s.worst_response)
                               for s in c.stats.values()))
            for r, c in sorted(w.cpus.items())}


def same_cpu_run(cfg: SimConfig, cuts: list[tuple[int, bool]], costs=None) -> bool:
    """On the CPU model: does the run with the fast paths (lone handlers, late bytes on an
    idle CPU: docs/fast-paths.md), cut at ``cuts``, give the events, summary and CPU figures
    of the run with every byte at its tick and every handler on the general path, and, once
    every station has looked at its UART, its state but for the CPUs and the fast paths' own
    forms (:func:`cpu_state`)? ``costs``: a cost table (default: the shipped one)."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    cfg = replace(cfg, cpu=costs or DEFAULT_COSTS)
    slow_events: list[dict] = []
    fast_events: list[dict] = []
    slow = World(replace(cfg, fast_paths=False), on_event=slow_events.append)
    slow.run()
    fast = World(cfg, on_event=fast_events.append)
    for tick, wake in cuts:
        (fast.run if wake else fast._advance)(tick)
    fast.run()
    if not (summary(fast) == summary(slow) and fast_events == slow_events
            and cpu_figures(fast) == cpu_figures(slow)):
        return False
    for w in (fast, slow):
        looked_at(w)
    return cpu_state(fast, forms=True) == cpu_state(slow, forms=True)


def cpu_state(w: World, forms: bool = False) -> list:
    """:func:`state` without the CPUs (their pending handlers hold ghosts or the real
    handlers: the same figures, a different form; :func:`cpu_figures` compares those) and
    without the UARTs' count of bytes handed over late (``Uart.bytes_late``: a figure of the
    fast path's, which a ghost the CPU took without an event leaves late where a real
    handler made them come on time). ``forms``: without the fast paths' own forms too, to
    compare a run with them against one without (:func:`same_cpu_run`): the switches
    themselves, the MAC's heartbeat length (its fast path's), a reception's clean prefix
    that may come late, and the timers' pending events (their ``expiry`` is compared: a
    timer re-armed later keeps an earlier event and moves it on when it fires)."""
    w.wake_can()
    parts = [p for _, q in sorted(w.quiet.items()) for p in q.roots]
    stations = [w.stations[r] for r in sorted(w.stations)]
    boundary = [w.sched, *w.quiet.values(), *(q.clock for q in w.quiet.values()),
                *w.cpus.values(), *(q.port for q in w.quiet.values())]
    aside: list[tuple[object, str, object]] = []

    def put_aside(obj: object, name: str, value: object) -> None:
        aside.append((obj, name, getattr(obj, name)))
        setattr(obj, name, value)

    for st in stations:
        put_aside(st.uart, "bytes_late", 0)
        if forms:
            put_aside(st.mac, "_hb_len", None)
            put_aside(st.mac, "cfg", replace(st.mac.cfg, fast_path=True))
            for timer in (st.timer, st.stall_timer):
                put_aside(timer, "_ev", None)
    if forms:
        put_aside(w.air, "byte_by_byte", False)
        for r in w.air.radios:
            if r.rx is not None:
                put_aside(r.rx, "quiet", 0)
                put_aside(r.rx, "lazy", 0)
    try:
        return portable(snapshot([*parts, stations, w.air], boundary, rng_state=True))
    finally:
        for obj, name, value in reversed(aside):
            setattr(obj, name, value)


def looked_at(w: World) -> None:
    """Every radio's firmware (the standby father's too) reads its UART now (``Uart.sync``):
    what a reception's burst or a late frame still holds of the bytes handed over by now is
    taken, as a look at the state would take it. A run with every byte at its tick has taken
    them already."""
    for r in w.air.radios:
        if r.uart is not None:
            r.uart.sync(w.sched.now)


def same_sleeping_cpu_run(cfg: SimConfig, cuts: list[tuple[int, bool]], costs=None) -> bool:
    """On the CPU model, untraced: does the run whose CAN sides sleep (their interrupts raised
    as ghosts: hil/sim/can_ghosts.py), cut at ``cuts``, end where the run whose CAN sides
    never sleep does, cut alike: summary, state and every handler's figures? (Cut alike: on
    the CPU model a cut hands the bytes an idle CPU holds over then, which moves the count of
    late bytes, a figure of the fast path's, and nothing else.)"""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    cfg = replace(cfg, cpu=costs or DEFAULT_COSTS)
    slow = World(replace(cfg, can_sleep=False))
    fast = World(cfg)
    for w in (slow, fast):
        for tick, wake in cuts:
            (w.run if wake else w._advance)(tick)
        w.run()
    return (summary(fast) == summary(slow) and cpu_figures(fast) == cpu_figures(slow)
            and cpu_state(fast) == cpu_state(slow))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0, help="first world's seed (default 0)")
    ap.add_argument("--runs", type=int, default=100, help="worlds to draw (default 100)")
    ap.add_argument("--cpu", action="store_true", help="the CPU model's fast paths instead: "
                    "each world on --cpu estimated with and without the fast paths")
    ap.add_argument("--cpu-costs", metavar="FILE", default=None,
                    help="with --cpu: this cost table (TOML, as rprs sim --cpu-costs) instead "
                    "of the shipped one; slow handlers meet where the shipped ones do not")
    a = ap.parse_args(argv)
    costs = None
    if a.cpu_costs is not None:
        if not a.cpu:
            ap.error("--cpu-costs goes with --cpu")
        from firmware_model.cycle_costs import load_costs
        try:
            costs = load_costs(a.cpu_costs)
        except (OSError, ValueError) as exc:
            ap.error(str(exc))
    bad = 0
    for seed in range(a.seed, a.seed + a.runs):
        cfg, cuts, traced = random_world(seed)
        t = time.perf_counter()
        ok = (same_cpu_run(cfg, cuts, costs) and same_sleeping_cpu_run(cfg, cuts, costs)) \
            if a.cpu \
            else same_run(cfg, cuts, traced) and same_bytewise_run(cfg)
        bad += not ok
        print(f"seed {seed}: {'same run' if ok else 'DIFFERENT'} ({time.perf_counter() - t:.1f} s)"
              + ("" if ok else f"\n  {cfg!r}\n  cuts {cuts}, traced {traced}"), flush=True)
    print(f"{a.runs} worlds, {bad} different")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
