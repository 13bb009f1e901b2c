"""The whole child under steady traffic: a loaded ring's cost with and without its CAN sides,
and with the CPU model, per radio frame (docs/performance.md, "Targets").

    python benchmarks/can_traffic.py [--seconds 60] [--rounds 3]

The 5-robot ring with the father (``--robots 0,1,2,3,4 --load 2``, seed 1): every child's
orders are motions, so its CAN side never sleeps. Three modes, each run in a fresh process
(benchmarks/fresh_process.py), alternated ``rounds`` times; the figure is wall time per radio
frame, the median of the rounds, and the ratios are taken within the run. Per frame, because
the traffic differs: with a CAN side the children carry out their orders and answer them
(longer frames, fewer of them in a simulated second).

* ``radio``: no CAN side (``can=False``);
* ``can``: every child's CAN side, the ideal CPU;
* ``can + cpu``: the same on the CPU model (``--cpu estimated``).

Targets: ``radio`` / ``can`` >= 0.3 (the CAN side at most 3.3x a frame's cost), and ``can +
cpu`` within 1.5x of ``can``.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import statistics

from fresh_process import timed

ROBOTS = (0, 1, 2, 3, 4)
MODES = {
    "radio": dict(can=False),
    "can": dict(can=True),
    "can + cpu": dict(can=True, cpu="estimated"),
}


def measure(seconds: float, rounds: int) -> dict[str, dict]:
    """Per mode: wall s per radio frame of each round, the frames, the median."""
    out: dict[str, dict] = {m: {"per_frame": [], "frames": None} for m in MODES}
    for _ in range(rounds):
        for mode, kw in MODES.items():
            kw = dict(kw)
            can = kw.pop("can")
            wall, frames = timed(ROBOTS, seconds, can=can, load=2.0, seed=1, **kw)
            out[mode]["per_frame"].append(wall / frames)
            out[mode]["frames"] = frames
    for m in out.values():
        m["median_ms"] = statistics.median(m["per_frame"]) * 1000
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--rounds", type=int, default=3)
    a = p.parse_args()
    r = measure(a.seconds, a.rounds)
    for mode, m in r.items():
        print(f"{mode:10s} {m['median_ms']:.3f} ms of wall time a radio frame "
              f"({m['frames']} frames, {a.seconds:g} simulated s, median of {a.rounds})")
    radio, can, cpu = (r[m]["median_ms"] for m in MODES)
    print(f"radio / can: {radio / can:.2f} (target >= 0.3); can + cpu / can: {cpu / can:.2f} "
          f"(target <= 1.5)")


if __name__ == "__main__":
    main()
