"""Simulator speed: simulated seconds per wall second, and the cost of a simulated frame.

    python benchmarks/sim_speed.py [--runs 5] [--seconds 300] [--quick]

Rings of 3, 4 and 7 robots (7 = the father and six children), idle, saturated and with byte
errors, radio side alone and with every child's CAN side (``--can``). Each figure is the
median of ``--runs`` runs, each in a process of its own (benchmarks/fresh_process.py says
why); the machine is shared, so compare ratios within a run. Prints a
Markdown table.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import os
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fresh_process import timed  # noqa: E402

RINGS = {3: (1, 2, 3), 4: (1, 2, 3, 4), 7: (0, 1, 2, 3, 4, 5, 6)}
LOADS = {"idle": {}, "saturated": {"load": "saturate"}, "BER 1e-3": {"ber": 1e-3}}


def measure(robots, seconds: float, runs: int, can: bool, **kw) -> tuple[float, float, int]:
    speeds, costs, frames = [], [], 0
    for _ in range(runs):
        wall, frames = timed(robots, seconds, can, **kw)
        speeds.append(seconds / wall)
        costs.append(wall / max(1, frames) * 1e6)
    return statistics.median(speeds), statistics.median(costs), frames


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--seconds", type=float, default=300.0, help="simulated seconds a run")
    p.add_argument("--quick", action="store_true", help="3 runs of 60 s; CAN runs of 20 s")
    a = p.parse_args()
    runs, secs = (3, 60.0) if a.quick else (a.runs, a.seconds)
    print("| robots | load | CAN side | speed (x real time) | wall us per frame | frames |")
    print("|---|---|---|---|---|---|")
    for n, robots in RINGS.items():
        for name, kw in LOADS.items():
            for can in (False, True):
                s = secs if not can else max(20.0, secs / 5)
                speed, cost, frames = measure(robots, s, runs if not can else max(1, runs // 2),
                                              can, **kw)
                print(f"| {n} | {name} | {'on' if can else 'off'} | {speed:,.0f} | {cost:.1f} | "
                      f"{frames} |", flush=True)


if __name__ == "__main__":
    main()
