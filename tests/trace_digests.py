"""Digests of the simulator's traces for a fixed set of seeded runs, through ``rprs sim`` (the
runs a user would type): test data, shared by the tests and scripts/trace_digest.py.

A change meant to leave behaviour alone (a restructuring, a speed-up: traces byte-identical
for the same seeds) must leave every digest as it was.
``tests/hil/sim/test_trace_digests.py`` compares them with the ones recorded in
``tests/data/trace_digests.txt``; ``python scripts/trace_digest.py`` prints them, ``--write``
records them again when a change of behaviour is meant (say why in the commit).

Each run covers a different part of the firmware and the air: a loaded ring with the father,
every child's CAN side with CAN faults and a cruising wheel, byte errors with idle noise, a
forced collision and a foreign burst with the checksum, a father failover, a father with no
standby back from a short outage (no probation: MacConfig.paired), power-on order with
clock skew and dropped bytes, and the peer MACs; each on both CPUs.
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import os
import tempfile
from pathlib import Path

__all__ = ["RUNS", "RECORDED", "digest", "read_recorded"]

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
    "lone father outage": "--robots 0,1,2 --duration 20 --seed 9 --load 1 --checksum "
                          "--fault fail:0@2 --fault recover:0@3",
    "power-on order and skew": "--robots 1,2,3,4,5 --duration 20 --seed 6 --power 3@1.5 "
                               "--power 1@0.7 --fault skew:2:0.02 --fault drop@5-9:0.002",
    "csma peer": "--robots 1,2,3 --duration 10 --seed 7 --mac csma --load 5",
}
"""Name: the ``rprs sim`` options of the run (``--trace`` is added). Each runs on the command
line's default CPU, the MB90F549 model (docs/cpu.md), and again with ``--cpu ideal`` (the
paper's zero-time CPU, the Python API's default): the runs below with ", ideal CPU"."""
RUNS.update({f"{name}, ideal CPU": f"{args} --cpu ideal" for name, args in list(RUNS.items())})

RECORDED = Path(__file__).resolve().parent / "data" / "trace_digests.txt"
"""The digests recorded at the last change of behaviour: ``<sha256>  <name>`` a line."""


def digest(args: str) -> str:
    """SHA-256 of the trace ``rprs sim <args> --trace FILE`` writes (run in this process)."""
    from hil.cli import main

    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "trace.jsonl")
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            status = main(["sim", *args.split(), "--trace", path, "--no-progress", "--json"])
        if status:
            raise RuntimeError(f"rprs sim {args} failed ({status}): {err.getvalue().strip()}")
        with open(path, "rb") as f:
            return hashlib.sha256(f.read()).hexdigest()


def read_recorded(path: Path = RECORDED) -> dict[str, str]:
    """Name -> recorded digest."""
    out: dict[str, str] = {}
    for line in path.read_text().splitlines():
        if line.strip():
            h, _, name = line.partition("  ")
            out[name] = h
    return out
