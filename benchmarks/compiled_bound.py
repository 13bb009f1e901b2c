"""What a compiled hot path could give at most: each workload's run split by the module whose
own code was running, and the speed-up if a set of modules cost nothing (issue 14).

    python benchmarks/compiled_bound.py [--rate 400] [--seconds 300] [--only loaded,soak]

Each workload runs in its own process under ``py-spy record --format raw`` (needs the bench
extra: ``pip install -e '.[bench]'``). A sample is charged to the module of its innermost
Python frame (its *own* time: what that module's lines and the built-ins they call cost), and
only samples inside ``World.run`` count (the benchmarks time the run, not the imports or the
world's construction). If the modules of a group took no time at all, the run would take
``1 - share`` of its time: ``1 / (1 - share)`` is an upper bound on what compiling that group,
however well, can give (Amdahl). Calls into the group from code that stays Python are charged
to the caller, so the bound is generous. Prints Markdown tables (docs/performance.md).
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from typing import Iterable

RING = (0, 1, 2, 3, 4, 5, 6)

GROUPS: dict[str, tuple[str, ...]] = {
    "scheduler": ("firmware_model/mcu/scheduler.py",),
    "CAN bus": ("can_bus/",),
    "CAN node firmware": ("firmware_model/mcu/can_controller.py", "firmware_model/mcu/cpu.py",
                          "firmware_model/child.py", "firmware_model/dispatcher.py",
                          "firmware_model/kinematics.py"),
    "radio path": ("hil/sim/air.py", "firmware_model/mcu/ptr2000.py",
                   "firmware_model/mcu/uart.py", "firmware_model/mcu/reload_timer.py",
                   "firmware_model/mcu/gpio.py", "firmware_model/station.py",
                   "firmware_model/radio/"),
    "snapshots (quiet CAN)": ("hil/sim/state_walk.py", "hil/sim/quiet_can.py"),
}
"""Module groups, by path prefix (relative to the checkout); anything else is "the rest"."""

BOUNDS: dict[str, tuple[str, ...]] = {
    "scheduler + CAN bus (the issue's suggestion)": ("scheduler", "CAN bus"),
    "scheduler + radio path": ("scheduler", "radio path"),
    "scheduler + CAN bus + CAN node firmware + radio path": (
        "scheduler", "CAN bus", "CAN node firmware", "radio path"),
}

WORKLOADS: dict[str, str] = {
    "idle 7-robot ring, radio only": (
        "from hil.sim.world import SimConfig, World\n"
        "World(SimConfig(robots={ring!r}, duration={seconds}, ring_sleep=False)).run()\n"),
    "saturated 7-robot ring, --can": (
        "from hil.sim.world import SimConfig, World\n"
        "World(SimConfig(robots={ring!r}, duration={seconds}, can=True, "
        "load='saturate')).run()\n"),
    "rprs soak --hours 0.1 --seed 11": (
        "from hil.sim.soak import run_soak\n"
        "run_soak(0.1, 11)\n"),
    "loaded 5-ring, --can (--load 2 --seed 1)": (
        "from hil.sim.world import SimConfig, World\n"
        "World(SimConfig(robots=(0, 1, 2, 3, 4), duration={seconds}, can=True, load=2.0, "
        "seed=1)).run()\n"),
}

NEEDED = {
    "idle 7-robot ring, radio only": ("25x the SimPy peer", 25 / 12.8),
    "saturated 7-robot ring, --can": ("CAN on / off >= 0.5", 0.5 / 0.43),
    "rprs soak --hours 0.1 --seed 11": ("4x the issue's main", 4 / 1.59),
    "loaded 5-ring, --can (--load 2 --seed 1)": ("radio / can >= 0.3 a radio frame", 0.3 / 0.11),
}
"""The speed-up each target still needs, from the last measured figures (docs/performance.md:
radio only 12.8x the SimPy peer, saturated on/off 0.43 over 60 s
(0.49 over 600 s, 0.56 over 1200 s), soak 1.59x the issue's main, the loaded ring's radio / can
0.11); update them with the figures of ``speed_targets.py``, ``soak_against.py`` and
``can_traffic.py``."""


def own_time(raw_lines: Iterable[str], root: str, inside: str = "World.run") -> Counter:
    """Samples by the file of the innermost frame, of the stacks that pass through
    ``inside`` (py-spy's raw format: ``frame;frame;... count``, a frame
    ``function (path:line)``); paths are made relative to ``root``."""
    out: Counter = Counter()
    for line in raw_lines:
        stack, _, count = line.rstrip("\n").rpartition(" ")
        if not stack or not count.isdigit():
            continue
        frames = stack.split(";")
        if not any(f.startswith(inside + " (") for f in frames):
            continue
        leaf = frames[-1]
        path = leaf[leaf.rfind("(") + 1:].rpartition(":")[0] if "(" in leaf else leaf
        if path.startswith(root):
            path = path[len(root):].lstrip("/")
        out[path] += int(count)
    return out


def group_shares(samples: Counter) -> dict[str, float]:
    """Share of the samples in each of :data:`GROUPS`, and ``"the rest"``."""
    total = sum(samples.values())
    shares = {g: 0.0 for g in GROUPS}
    rest = 0
    for path, n in samples.items():
        for g, prefixes in GROUPS.items():
            if path.startswith(prefixes):
                shares[g] += n / total
                break
        else:
            rest += n
    shares["the rest"] = rest / total
    return shares


def bound(shares: dict[str, float], groups: Iterable[str]) -> float:
    """Amdahl: the speed-up if ``groups`` cost nothing."""
    gone = sum(shares[g] for g in groups)
    return float("inf") if gone >= 1.0 else 1.0 / (1.0 - gone)


def py_spy() -> str | None:
    """The py-spy program: beside this interpreter (a venv not on PATH), else on PATH."""
    here = os.path.join(os.path.dirname(sys.executable), "py-spy")
    return here if os.access(here, os.X_OK) else shutil.which("py-spy")


def profile(code: str, rate: int, root: str) -> Counter:
    """Run ``code`` in a fresh interpreter under py-spy; its own-time samples."""
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "raw.txt")
        cmd = [py_spy() or "py-spy", "record", "--rate", str(rate), "--format", "raw",
               "--output", out, "--", sys.executable, "-c", code]
        env = dict(os.environ, PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
        subprocess.run(cmd, check=True, capture_output=True, env=env, cwd=root)
        with open(out) as f:
            return own_time(f, root)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rate", type=int, default=400, help="py-spy samples a second")
    p.add_argument("--seconds", type=float, default=300.0,
                   help="simulated seconds of the ring workloads")
    p.add_argument("--only", default="", help="comma-separated words; run only the workloads "
                   "whose name holds one of them (e.g. --only loaded)")
    a = p.parse_args()
    words = [w for w in a.only.split(",") if w]
    chosen = {n: c for n, c in WORKLOADS.items() if not words or any(w in n for w in words)}
    if not chosen:
        p.error(f"--only {a.only!r} names no workload: {', '.join(WORKLOADS)}")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if py_spy() is None:
        print("py-spy is not installed: pip install -e '.[bench]'", file=sys.stderr)
        return 2
    rows = []
    for name, code in chosen.items():
        samples = profile(code.format(ring=RING, seconds=a.seconds), a.rate, root)
        rows.append((name, sum(samples.values()), group_shares(samples)))
    cols = [*GROUPS, "the rest"]
    print("| workload (own time inside World.run) | samples | " + " | ".join(cols) + " |")
    print("|---|---|" + "---|" * len(cols))
    for name, n, shares in rows:
        print(f"| {name} | {n:,} | " + " | ".join(f"{shares[c]:.0%}" for c in cols) + " |")
    print("\n| workload | target needs (from the figures in NEEDED) | "
          + " | ".join(f"at most, {b} compiled to nothing" for b in BOUNDS) + " |")
    print("|---|---|" + "---|" * len(BOUNDS))
    for name, _, shares in rows:
        what, need = NEEDED[name]
        print(f"| {name} | {need:.2f}x ({what}) | " +
              " | ".join(f"{bound(shares, g):.2f}x" for g in BOUNDS.values()) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
