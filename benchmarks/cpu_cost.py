"""What the CPU model costs against the ideal CPU, on the rings people run
(docs/performance.md, "Targets"; docs/cpu.md).

    python benchmarks/cpu_cost.py [--rounds 3] [--only idle-radio,loaded-radio,...]

Each workload runs with ``--cpu ideal`` and ``--cpu estimated`` (the default cost table), each
run in a fresh process (benchmarks/fresh_process.py), the two alternated ``rounds`` times; the
figure is the run's wall time (start-up excluded), the median of the rounds, and the ratio is
taken within the run:

* ``idle-radio``: the idle 7-robot ring, radio only, an hour (the ring leaps on both CPUs);
* ``loaded-radio``: 4 robots with the father at ``--load 1``, radio only, 300 s;
* ``idle-can``: the idle 7-robot ring with every child's CAN side, 60 s (the CAN sides sleep
  on both CPUs, on the CPU model their interrupts raised as ghosts; there their handlers meet
  the radio's on one CPU at ticks no ring cycle repeats, so the ring does not leap);
* ``idle-can-hour``: the same for an hour, where users leave a ring running: the ideal CPU's
  ring leaps, the CPU model's runs every frame, so the ratio grows with the run's length;
* ``loaded-can``: the 5-robot ring with the father at ``--load 2`` with CAN sides, 30 s
  (benchmarks/can_traffic.py's ``can`` and ``can + cpu``).

Target: every ratio within 1.5 (issue "Fast in every mode people run").
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import statistics

from fresh_process import timed

WORKLOADS: dict[str, tuple[tuple[int, ...], float, dict]] = {
    "idle-radio": ((0, 1, 2, 3, 4, 5, 6), 3600.0, {}),
    "loaded-radio": ((0, 1, 2, 3), 300.0, dict(load=1.0)),
    "idle-can": ((0, 1, 2, 3, 4, 5, 6), 60.0, dict(can=True)),
    "idle-can-hour": ((0, 1, 2, 3, 4, 5, 6), 3600.0, dict(can=True)),
    "loaded-can": ((0, 1, 2, 3, 4), 30.0, dict(can=True, load=2.0)),
}


def measure(names: list[str], rounds: int) -> dict[str, dict[str, float]]:
    """Per workload: the median wall s with each CPU, and their ratio."""
    walls: dict[str, dict[str, list[float]]] = {n: {"ideal": [], "estimated": []}
                                                for n in names}
    for _ in range(rounds):
        for name in names:
            robots, seconds, kw = WORKLOADS[name]
            kw = dict(kw)
            can = kw.pop("can", False)
            for cpu in ("ideal", "estimated"):
                extra = dict(kw, cpu="estimated") if cpu == "estimated" else kw
                wall, _ = timed(robots, seconds, can=can, seed=1, **extra)
                walls[name][cpu].append(wall)
    out = {}
    for name, w in walls.items():
        ideal, est = statistics.median(w["ideal"]), statistics.median(w["estimated"])
        out[name] = {"ideal": ideal, "estimated": est, "ratio": est / ideal}
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--only", default=",".join(WORKLOADS),
                   help="workloads, comma-separated (default: all)")
    a = p.parse_args()
    names = [n for n in a.only.split(",") if n]
    unknown = [n for n in names if n not in WORKLOADS]
    if unknown:
        p.error(f"unknown workload {unknown[0]!r}; choose from {', '.join(WORKLOADS)}")
    for name, r in measure(names, a.rounds).items():
        robots, seconds, kw = WORKLOADS[name]
        print(f"{name:13s} ideal {r['ideal']:8.3f} s  estimated {r['estimated']:8.3f} s  "
              f"ratio {r['ratio']:5.2f}  ({len(robots)} robots, {seconds:g} simulated s, "
              f"median of {a.rounds})")


if __name__ == "__main__":
    main()
