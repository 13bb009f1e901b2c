"""One timed simulator run in a process of its own (the speed benchmarks' runs).

The model remembers pure results (commands, Content, parsed frames, CAN frames). Runs timed
one after another in one process with the same seed find the previous run's results in those
memos: a warm model that no user's single ``rprs sim`` is. So each timed run starts a Python
of its own, with this checkout first on ``sys.path``, and reports its wall time (the run
alone, not the start-up) and the radio frames it carried.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
"""This checkout."""
ENV = dict(os.environ, PYTHONPATH=ROOT + os.pathsep +
           os.environ.get("PYTHONPATH", ""))
"""The environment of a benchmark's child process: this checkout importable."""

_RUN = """
import gc, json, sys, time
sys.path.insert(0, {here!r})
kind, robots, seconds, can, kw = {args!r}
if kind == "simpy":
    import simpy_ring
    gc.collect()
    r = simpy_ring.run(robots, seconds)
    wall, frames = r["wall"], r["frames"]
else:
    from hil.sim.world import SimConfig, World
    if kw.get("cpu") == "estimated":         # the CPU model with the default cost table
        from firmware_model.cycle_costs import DEFAULT_COSTS
        kw["cpu"] = DEFAULT_COSTS
    w = World(SimConfig(robots=robots, duration=seconds, can=can, **kw))
    gc.collect()
    t0 = time.perf_counter()
    w.run()
    wall, frames = time.perf_counter() - t0, w.air.occupations
print(json.dumps([wall, frames]))
"""


def timed(robots: tuple[int, ...], seconds: float, can: bool = False, simpy: bool = False,
          **kw) -> tuple[float, int]:
    """(wall s, radio frames) of one run of ``robots`` for ``seconds`` simulated seconds
    (``kw``: more SimConfig fields; ``cpu="estimated"``: the CPU model with the default cost
    table), or of the SimPy peer (benchmarks/simpy_ring.py)."""
    code = _RUN.format(here=HERE, args=("simpy" if simpy else "ours", robots, seconds, can, kw))
    # started in the checkout: ``python -c`` puts its working directory first on sys.path,
    # so a run started elsewhere could import another tree's hil
    out = subprocess.run([sys.executable, "-c", code], check=True, env=ENV, cwd=ROOT,
                         capture_output=True, text=True).stdout
    wall, frames = json.loads(out)
    return wall, frames
