"""Run every benchmark and print the figures (docs/performance.md records them).

    python benchmarks/run.py [--quick]

Each script can also run alone: sim_speed.py, speed_targets.py, mac_efficiency.py, peer_macs.py,
realtime_fidelity.py, checksum_effect.py.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPTS = [
    ("Simulator speed", "sim_speed.py", []),
    ("The whole child against the speed targets", "speed_targets.py", []),
    ("MAC efficiency, failure detection and rejoin", "mac_efficiency.py", []),
    ("Peer MACs on the same channel", "peer_macs.py", []),
    ("What the checksum buys", "checksum_effect.py", []),
    ("Real-time fidelity", "realtime_fidelity.py", []),
]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="smaller runs (a few minutes)")
    a = p.parse_args()
    env = dict(os.environ, PYTHONPATH=os.path.dirname(HERE) + os.pathsep +
               os.environ.get("PYTHONPATH", ""))
    status = 0
    for title, script, extra in SCRIPTS:
        args = list(extra)
        if a.quick and script in ("sim_speed.py", "mac_efficiency.py", "peer_macs.py"):
            args.append("--quick")
        if a.quick and script == "speed_targets.py":
            args += ["--runs", "1", "--seconds", "30"]
        if a.quick and script == "realtime_fidelity.py":
            args += ["--seconds", "5", "--samples", "8"]
        print(f"\n## {title}\n", flush=True)
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, os.path.join(HERE, script), *args], env=env)
        print(f"\n({script}: {time.perf_counter() - t0:.0f} s)", flush=True)
        status |= r.returncode
    return status


if __name__ == "__main__":
    sys.exit(main())
