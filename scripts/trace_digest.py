"""Digests of the simulator's traces for a fixed set of seeded runs, through the ``rprs sim``
command a user runs. A change meant to leave behaviour alone (a restructuring, a speed-up)
must leave every digest unchanged:

    python scripts/trace_digest.py > before.txt      # on the old commit
    python scripts/trace_digest.py | diff before.txt -   # on the new one

Each run covers a different part of the firmware and the air: a loaded ring with the father,
every child's CAN side with CAN faults, byte errors with idle noise, a forced collision and a
foreign burst with the checksum, a father failover, and the peer MACs.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile

RUNS = {
    "loaded ring of 7": "--robots 0,1,2,3,4,5,6 --duration 30 --seed 1 --load 2",
    "CAN side and CAN faults": "--robots 0,1,2,3 --duration 20 --seed 2 --can --load 1 "
                               "--fault busoff:2@4 --fault stuck:3@6-7 "
                               "--fault stall:1.JOINT1@5 --fault silent:2.WHEEL@8-9",
    "byte errors and noise": "--robots 1,2,3,4 --duration 20 --seed 3 --ber 0.001 --noise "
                             "--load 1",
    "collision, burst, checksum": "--robots 0,1,2,3 --duration 20 --seed 4 --checksum --load 1 "
                                  "--fault steal:2@3 --fault burst@6:0.3 --fault fail:1@8 "
                                  "--fault recover:1@12",
    "father failover": "--robots 0,1,2 --duration 20 --seed 5 --father-standby --load 1 "
                       "--fault fail:0@6",
    "power-on order and skew": "--robots 1,2,3,4,5 --duration 20 --seed 6 --power 3@1.5 "
                               "--power 1@0.7 --fault skew:2:0.02 --fault drop@5-9:0.002",
    "csma peer": "--robots 1,2,3 --duration 10 --seed 7 --mac csma --load 5",
}


def digest(args: str) -> str:
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "trace.jsonl")
        cmd = [sys.executable, "-m", "hil.cli", "sim", *args.split(), "--trace", path,
               "--no-progress", "--json"]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode:
            raise SystemExit(f"rprs sim {args} failed ({r.returncode}): {r.stderr.strip()}")
        with open(path, "rb") as f:
            return hashlib.sha256(f.read()).hexdigest()


def main() -> int:
    for name, args in RUNS.items():
        print(f"{digest(args)}  {name}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
