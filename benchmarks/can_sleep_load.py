"""Sleeping CAN sides under load: what a sleep costs against what it saves, and the runs with
and without sleeping (docs/performance.md, "Sleeping CAN sides under load").

    python benchmarks/can_sleep_load.py [--seconds 120] [--rounds 3] [--cpu]

A child's CAN side sleeps after two snapshots a status period apart match
(hil/sim/quiet_can.py); a message to the child wakes it. Under load the sleeps are short, and
a domain whose sleeps keep ending before ``PAYBACK_PERIODS`` backs off its probes. Printed:

* the median wall time of one snapshot of a child's CAN side, taken on the loaded ring, and
  what one status period of an idle child's CAN side costs run frame by frame (the CAN side's
  share of an every-frame ring: the same ring without ``--can`` subtracted);
* for the 5-robot ring with the father at 0.2, 0.5 and 2 messages a second a robot (seed 1,
  ``--can``, the ideal CPU, as SimConfig's default): the wall time of the run with sleeping
  CAN sides and with ``can_sleep=False``, each in a fresh process (benchmarks/fresh_process.py),
  alternated ``rounds`` times, medians; their ratio (below 1: sleeping pays).

``--cpu``: the same ring on the CPU model (``--cpu estimated``, the command line's default),
idle and at 0.5 and 2 messages a second a robot, where a sleeping side's interrupts come as
ghosts (hil/sim/can_ghosts.py); the snapshot and period costs are the ideal CPU's and are not
printed.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import statistics
import time

from fresh_process import timed

ROBOTS = (0, 1, 2, 3, 4)
LOADS = (0.2, 0.5, 2.0)
CPU_LOADS: tuple[str | float, ...] = ("idle", 0.5, 2.0)


def costs(seconds: float) -> tuple[float, float]:
    """(median ms a snapshot of a loaded child's CAN side, ms a status period of an idle
    child's CAN side run frame by frame)."""
    import hil.sim.quiet_can as quiet_can
    from hil.sim.world import SimConfig, World
    spent: list[float] = []
    real = quiet_can.snapshot

    def timed_snapshot(*a, **k):
        t = time.perf_counter()
        try:
            return real(*a, **k)
        finally:
            spent.append(time.perf_counter() - t)

    quiet_can.snapshot = timed_snapshot
    try:
        World(SimConfig(robots=ROBOTS, duration=seconds, can=True, seed=1, load=2.0)).run()
    finally:
        quiet_can.snapshot = real
    walls = []
    for can in (True, False):
        w = World(SimConfig(robots=ROBOTS, duration=seconds, can=can, seed=1,
                            fast_paths=False))
        t = time.perf_counter()
        w.run()
        walls.append(time.perf_counter() - t)
    children = len(ROBOTS) - 1
    periods = seconds * 16_000_000 // quiet_can.PERIOD
    return statistics.median(spent) * 1e3, (walls[0] - walls[1]) / (children * periods) * 1e3


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=120.0)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--cpu", action="store_true", help="on the CPU model (--cpu estimated)")
    a = p.parse_args()
    extra = {"cpu": "estimated"} if a.cpu else {}
    if not a.cpu:
        snap_ms, period_ms = costs(a.seconds)
        print(f"a snapshot of a loaded child's CAN side: {snap_ms:.3f} ms (median); "
              f"an idle child's status period run frame by frame: {period_ms:.3f} ms "
              f"({snap_ms / period_ms:.1f} periods a snapshot)")
    for load in CPU_LOADS if a.cpu else LOADS:
        walls: dict[bool, list[float]] = {True: [], False: []}
        for _ in range(a.rounds):
            for sleep in (True, False):
                wall, _ = timed(ROBOTS, a.seconds, can=True, load=load, seed=1,
                                can_sleep=sleep, **extra)
                walls[sleep].append(wall)
        on, off = statistics.median(walls[True]), statistics.median(walls[False])
        print(f"--load {load}: sleeping CAN sides {on:.2f} s, never sleeping {off:.2f} s, "
              f"ratio {on / off:.2f} (median of {a.rounds}, {a.seconds:g} simulated s"
              + (", the CPU model)" if a.cpu else ")"))


if __name__ == "__main__":
    main()
