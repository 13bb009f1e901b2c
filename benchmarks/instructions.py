"""Instructions the simulator executes for fixed workloads, counted by valgrind's callgrind:
a speed figure that is the same on every run of the same tree, however busy the machine is.

    python benchmarks/instructions.py [--base COMMIT] [--only idle,saturated,soak]

Wall times on a shared 2-core machine move by 20-40 % from run to run (docs/performance.md),
so a change worth 3 % cannot be seen in them without dozens of runs. The count of machine
instructions can: with ``PYTHONHASHSEED=0`` the same files give the same count to the
instruction, run after run; only the memory layout (sets of objects iterate in address order)
moves it, by up to 0.4 % between two states of the same tree (a source file newer than its
cached bytecode), so differences under 1 % say nothing. It is not a time (a cache miss costs
more than an add), so the wall-time benchmarks stay the judges of the targets; this one says
whether a change made the model do less, and roughly how much (10.7 % fewer instructions of
the idle ring were 13 % less CPU time: docs/performance.md).

Each workload runs in a process of its own under ``valgrind --tool=callgrind``, and only the
run is counted: the script calls it through ``functools.reduce`` and callgrind collects only
inside that C function (``--toggle-collect=functools_reduce``), so the interpreter's start, the
imports and the world's construction are left out. (Nothing in the model calls ``reduce``; if
libpython's symbols were stripped nothing would be counted, and the script says so.)

* ``idle``: the radio-only idle 7-robot ring, 60 simulated s, every frame run (no leap over
  the cycles it repeats: hil/sim/quiet_ring.py), the cost of the radio path itself;
* ``idle-cpu``: the same ring on the CPU model (the command line's default), 20 s, every
  frame run: what the handlers' machinery costs a frame;
* ``saturated``: the 7-robot ring with every child's CAN side, ``load=saturate``, 60 s;
* ``soak``: ``run_soak(0.05 h, seed 11)``, the whole soak (faults, traffic, CAN sides);
* ``soak-0.1``: ``run_soak(0.1 h, seed 11)``, the same with a larger share of traffic (not
  run unless named in ``--only``: 20-60 min under callgrind);
* ``loaded`` and ``loaded-every-frame``: 2 robots, a message a second, 960 s, in the default
  mode and with every fast path off: the default must not cost more (only with ``--only``);
* ``loaded-can`` and ``loaded-can-ideal``: benchmarks/cpu_cost.py's ``loaded-can`` (5 robots,
  CAN sides, load 2, 30 s) on the CPU model and on the ideal CPU (only with ``--only``);
* ``idle-can-cpu``: benchmarks/cpu_cost.py's ``idle-can`` (the idle 7-robot ring with CAN
  sides, 60 s) on the CPU model (only with ``--only``).

``--base COMMIT`` counts the same workloads in a temporary worktree of that commit too
(benchmarks/base_tree.py) and prints the ratio base / this tree. Needs valgrind (Debian's
package). A workload costs 30-120 s of wall time under callgrind.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import json
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from base_tree import ROOT, checkout, head_label, resolve  # noqa: E402  (benchmarks/ on sys.path)

RING = (0, 1, 2, 3, 4, 5, 6)

WORKLOADS: dict[str, str] = {
    "idle": f"""
from hil.sim.world import SimConfig, World
# every frame (trees before the ring's leaps have no ring_sleep, and run every frame anyway)
every = {{"ring_sleep": False}} if "ring_sleep" in SimConfig.__dataclass_fields__ else {{}}
w = World(SimConfig(robots={RING!r}, duration=60.0, can=False, **every))
run = w.run
done = lambda: (60.0, w.air.occupations)
""",
    # the CPU model (the command line's default) on the same ring, every frame run: its
    # handlers' machinery per frame (docs/cpu.md, "The default, and what it costs")
    "idle-cpu": f"""
from hil.sim.world import SimConfig, World
from firmware_model.cycle_costs import DEFAULT_COSTS
w = World(SimConfig(robots={RING!r}, duration=20.0, can=False, ring_sleep=False,
                    cpu=DEFAULT_COSTS))
run = w.run
done = lambda: (20.0, w.air.occupations)
""",
    "saturated": f"""
from hil.sim.world import SimConfig, World
w = World(SimConfig(robots={RING!r}, duration=60.0, can=True, load="saturate"))
run = w.run
done = lambda: (60.0, w.air.occupations)
""",
    "soak": """
from hil.sim.soak import run_soak
out = []
run = lambda: out.append(run_soak(0.05, 11))
done = lambda: (0.05 * 3600, out[0].summary["occupations"])
""",
    # the default mode against --every-frame where a ring is loaded (docs/performance.md,
    # "Targets": the default never slower): 2 robots, a message a second, 960 s
    "loaded": """
from hil.sim.world import SimConfig, World
w = World(SimConfig(robots=(1, 2), duration=960.0, load=1.0, seed=1))
run = w.run
done = lambda: (960.0, w.air.occupations)
""",
    "loaded-every-frame": """
from hil.sim.world import SimConfig, World
every = {"fast_paths": False} if "fast_paths" in SimConfig.__dataclass_fields__ else \
    {"ring_sleep": False}
w = World(SimConfig(robots=(1, 2), duration=960.0, load=1.0, seed=1, **every))
run = w.run
done = lambda: (960.0, w.air.occupations)
""",
    # the CPU model where it costs most against the ideal CPU (benchmarks/cpu_cost.py's
    # ``loaded-can``): the 5-ring, the father at load 2, CAN sides, 30 s; and on the ideal CPU
    "loaded-can": """
from hil.sim.world import SimConfig, World
from firmware_model.cycle_costs import DEFAULT_COSTS
w = World(SimConfig(robots=(0, 1, 2, 3, 4), duration=30.0, can=True, load=2.0, seed=1,
                    cpu=DEFAULT_COSTS))
run = w.run
done = lambda: (30.0, w.air.occupations)
""",
    "loaded-can-ideal": """
from hil.sim.world import SimConfig, World
w = World(SimConfig(robots=(0, 1, 2, 3, 4), duration=30.0, can=True, load=2.0, seed=1))
run = w.run
done = lambda: (30.0, w.air.occupations)
""",
    # the CPU model with CAN sides on an idle ring (benchmarks/cpu_cost.py's ``idle-can``):
    # the 7-ring, 60 s; its sleeping CAN sides' interrupts come as ghosts, and the ring
    # runs every frame (docs/fast-paths.md, "Sleeping CAN domains")
    "idle-can-cpu": """
from hil.sim.world import SimConfig, World
from firmware_model.cycle_costs import DEFAULT_COSTS
w = World(SimConfig(robots=(0, 1, 2, 3, 4, 5, 6), duration=60.0, can=True, cpu=DEFAULT_COSTS))
run = w.run
done = lambda: (60.0, w.air.occupations)
""",
    # the CPU model target's loaded radio-only ring (benchmarks/cpu_cost.py's
    # ``loaded-radio``): 4 robots with the father at load 1, 300 s; and on the ideal CPU
    "loaded-radio": """
from hil.sim.world import SimConfig, World
from firmware_model.cycle_costs import DEFAULT_COSTS
w = World(SimConfig(robots=(0, 1, 2, 3), duration=300.0, load=1.0, seed=1, cpu=DEFAULT_COSTS))
run = w.run
done = lambda: (300.0, w.air.occupations)
""",
    "loaded-radio-ideal": """
from hil.sim.world import SimConfig, World
w = World(SimConfig(robots=(0, 1, 2, 3), duration=300.0, load=1.0, seed=1))
run = w.run
done = lambda: (300.0, w.air.occupations)
""",
    # twice as long: 240 s of traffic and faults, 110 s of drain (the 0.05 h soak has 70 s
    # of traffic and 110 s of drain, which a ring that leaps over idle stretches runs cheaply)
    "soak-0.1": """
from hil.sim.soak import run_soak
out = []
run = lambda: out.append(run_soak(0.1, 11))
done = lambda: (0.1 * 3600, out[0].summary["occupations"])
""",
}
"""Each defines ``run()`` (what is counted) and ``done()`` -> (simulated s, radio frames)."""

_DRIVER = """
import functools, json, sys
sys.path.insert(0, {tree!r})
{setup}
functools.reduce(lambda _a, _b: run(), (0,), 0)
print(json.dumps(done()))
"""

_COLLECTED = re.compile(r"Collected\s*:\s*([\d,]+)")


class NoValgrind(RuntimeError):
    """valgrind is not installed, or it counted nothing (libpython without symbols)."""


def collected(stderr: str) -> int:
    """The instruction count callgrind printed ('==123== Collected : 1,234')."""
    m = _COLLECTED.search(stderr)
    if m is None:
        raise NoValgrind("callgrind printed no count:\n" + stderr[-1000:])
    return int(m.group(1).replace(",", ""))


def count(tree: str, workload: str) -> tuple[int, float, int]:
    """(instructions, simulated s, radio frames) of one run of ``workload`` from ``tree``."""
    if shutil.which("valgrind") is None:
        raise NoValgrind("valgrind is not installed (Debian: apt-get install valgrind)")
    code = _DRIVER.format(tree=tree, setup=WORKLOADS[workload])
    env = dict(os.environ, PYTHONPATH=tree, PYTHONHASHSEED="0")
    p = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
                        "--collect-atstart=no", "--toggle-collect=functools_reduce",
                        sys.executable, "-c", code], cwd=tree, env=env,
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"{workload} failed in {tree}:\n{p.stderr[-2000:]}")
    n = collected(p.stderr)
    if n == 0:
        raise NoValgrind("callgrind counted nothing: this libpython has no functools_reduce "
                         "symbol (stripped?)")
    seconds, frames = json.loads(p.stdout.strip().splitlines()[-1])
    return n, seconds, frames


def table(rows: list[tuple[str, int, float, int, int | None]], base: str | None) -> str:
    """Markdown: per workload, instructions per simulated s and per radio frame, and with a
    base, its count and base / this (above 1: this tree does less)."""
    head = "| workload | instructions | per simulated s | per radio frame |"
    rule = "|---|---|---|---|"
    if base is not None:
        head += f" {base} | {base} / this |"
        rule += "---|---|"
    out = [head, rule]
    for name, n, seconds, frames, b in rows:
        line = f"| {name} | {n:,} | {n / seconds:,.0f} | {n / max(frames, 1):,.0f} |"
        if base is not None and b is not None:
            line += f" {b:,} | {b / n:.3f} |"
        out.append(line)
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--base", help="also count a commit's tree and give the ratio")
    p.add_argument("--only", default=",".join(w for w in WORKLOADS
                                              if w not in ("soak-0.1", "loaded",
                                                           "loaded-every-frame", "loaded-can",
                                                           "loaded-can-ideal", "loaded-radio",
                                                           "loaded-radio-ideal",
                                                           "idle-can-cpu")),
                   help="comma-separated workloads (default: %(default)s)")
    a = p.parse_args(argv)
    names = [w for w in a.only.split(",") if w]
    unknown = [w for w in names if w not in WORKLOADS]
    if unknown or not names:
        p.error(f"unknown workload(s) {', '.join(unknown) or '(none given)'}; "
                f"known: {', '.join(WORKLOADS)}")
    if a.base is not None and resolve(a.base) is None:
        p.error(f"--base {a.base!r} is not a commit of {ROOT}")
    if shutil.which("valgrind") is None:
        print("valgrind is not installed (Debian: apt-get install valgrind)", file=sys.stderr)
        return 2
    here = head_label()
    rows = []
    try:
        if a.base is None:
            for w in names:
                n, s, f = count(ROOT, w)
                print(f"{w}: {n:,}", file=sys.stderr, flush=True)
                rows.append((w, n, s, f, None))
            base = None
        else:
            with checkout(a.base, prefix="instr-base-") as (base, tree):
                for w in names:
                    b = count(tree, w)[0]
                    n, s, f = count(ROOT, w)
                    print(f"{w}: {base} {b:,}, this tree {n:,}", file=sys.stderr, flush=True)
                    rows.append((w, n, s, f, b))
    except NoValgrind as exc:
        print(exc, file=sys.stderr)
        return 2
    print(f"Instructions of this tree ({here})" + (f" and of {base}" if base else "")
          + " (callgrind, PYTHONHASHSEED=0, the run only):\n")
    print(table(rows, base))
    return 0


if __name__ == "__main__":
    sys.exit(main())
