"""Cost per simulated second against the run's length: a loaded 2-robot ring, the default mode
and ``--every-frame`` (issue 46: longer runs must not get slower per simulated second, and the
default must never be slower than every frame; docs/performance.md, "Targets").

    python benchmarks/run_length.py [--durations 120,960,1920] [--runs 3]

Each run is a fresh process (``World(SimConfig(robots=(1, 2), duration=D, load=1.0, seed=1,
fast_paths=...)).run()``), timed by its CPU time around ``run()`` only; the runs alternate
durations and modes, and the table gives medians and the ratios of one series.
"""
from __future__ import annotations

if __name__ == "__main__":
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import statistics
import subprocess
import sys

RUN = """
import time
from hil.sim.world import SimConfig, World
w = World(SimConfig(robots=(1, 2), duration={d}, load=1.0, seed=1, fast_paths={fast}))
t = time.process_time()
w.run()
print(time.process_time() - t)
"""


def measure(durations: list[float], runs: int) -> dict[tuple[float, bool], float]:
    """Median CPU seconds of ``run()`` per (duration, fast paths on)."""
    times: dict[tuple[float, bool], list[float]] = {}
    for _ in range(runs):
        for d in durations:
            for fast in (True, False):
                out = subprocess.run([sys.executable, "-c", RUN.format(d=d, fast=fast)],
                                     capture_output=True, text=True, check=True)
                times.setdefault((d, fast), []).append(float(out.stdout))
    return {k: statistics.median(v) for k, v in times.items()}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--durations", default="120,960,1920",
                   help="simulated seconds, comma-separated (default: %(default)s)")
    p.add_argument("--runs", type=int, default=3, help="series (default: %(default)s)")
    a = p.parse_args(argv)
    durations = [float(x) for x in a.durations.split(",") if x]
    med = measure(durations, a.runs)
    first = durations[0]
    print("| simulated s | default CPU s | ms per simulated s | every frame CPU s | "
          "ms per simulated s | default / every frame | per simulated s / the shortest |")
    print("|---|---|---|---|---|---|---|")
    for d in durations:
        on, off = med[(d, True)], med[(d, False)]
        growth = (on / d) / (med[(first, True)] / first)
        print(f"| {d:,.0f} | {on:.2f} | {on / d * 1000:.2f} | {off:.2f} | "
              f"{off / d * 1000:.2f} | {on / off:.2f} | {growth:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
