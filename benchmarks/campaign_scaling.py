"""Campaign throughput: runs per second on 1 and 2 local workers, the scaling efficiency, and
the share of the workers' time not spent in runs (scheduling, transfers, the database).

    python benchmarks/campaign_scaling.py [--runs 40] [--duration 60] [--cpu ideal]

One grid point (the idle 5-robot ring with the father and the checksum, 1 message/s per
robot) and ``--runs`` seeds, run into a fresh results file for each worker count, with the
engine's default chunking (docs/campaigns.md). The children run on the CPU model, as a
campaign does by default; ``--cpu ideal`` puts ``cpu = ["ideal"]`` in the grid.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import os
import tempfile
import time
from pathlib import Path

from hil.campaign import engine
from hil.campaign.engine import run_campaign
from hil.campaign.runs import check_args
from hil.campaign.spec import load_spec
from hil.campaign.store import Store


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=40)
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--max-workers", type=int, default=os.cpu_count() or 1)
    p.add_argument("--cpu", choices=("ideal", "estimated"), default="estimated",
                   help="the children's CPU (default: the CPU model, a campaign's default)")
    a = p.parse_args()
    engine.source_state = lambda root=None: ("benchmark", False)   # results are thrown away
    with tempfile.TemporaryDirectory() as d:
        spec_file = Path(d) / "bench.toml"
        spec_file.write_text(f'[campaign]\nname = "bench"\nseeds = {a.runs}\n'
                             f'duration = {a.duration}\n[grid]\nrobots = ["0,1,2,3,4"]\n'
                             'load = ["1"]\nchecksum = [true]\n'
                             + (f'cpu = ["{a.cpu}"]\n' if a.cpu == "ideal" else ""))
        spec = load_spec(spec_file, check=check_args)
        print("| workers | runs | wall s | runs/s | efficiency | time not in runs |")
        print("|---|---|---|---|---|---|")
        base = None
        for w in range(1, a.max_workers + 1):
            store = Store(Path(d) / f"w{w}.sqlite")
            t0 = time.perf_counter()
            out = run_campaign(spec, store, workers=w)
            rate = out.ran / out.wall_s
            base = base or rate
            print(f"| {w} | {out.ran} | {out.wall_s:.1f} | {rate:.2f} | "
                  f"{rate / (base * w) * 100:.0f} % | {out.overhead * 100:.1f} % "
                  f"(with cluster start-up: {time.perf_counter() - t0:.1f} s) |", flush=True)
            store.close()


if __name__ == "__main__":
    main()
