"""What the command line's default CPU (the MB90F549 model) costs against ``--cpu ideal``, on
the commands people type (docs/cpu.md, "The default, and what it costs").

    python benchmarks/default_commands.py [--rounds 3] [--only demo,sim-can,...]

Each command runs as a whole process (``python -m hil.cli ...``: start-up included, as a user
waits for it), once as given (the CPU model) and once with ``--cpu ideal``, the two alternated
``rounds`` times; each figure is the median wall time, the ratio taken within the run.
Prints a Markdown table.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import statistics
import subprocess
import sys
import time

from fresh_process import ENV, ROOT

COMMANDS: dict[str, list[str]] = {
    "demo": ["demo"],
    "sim-can": ["sim", "--can"],
    "sim-600": ["sim", "--duration", "600"],
    "sim-can-600": ["sim", "--can", "--duration", "600"],
    "soak": ["soak", "--hours", "1"],
}
"""What each row runs (``rprs`` ARGS); ``--no-progress`` is added to the ``sim`` rows."""


def wall(args: list[str]) -> float:
    """Wall seconds of ``rprs ARGS`` in a process of its own (its output discarded)."""
    extra = ["--no-progress"] if args[0] == "sim" else []
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "hil.cli", *args, *extra], check=True, env=ENV,
                   cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--only", default=",".join(COMMANDS),
                    help="comma-separated rows (default: all): " + ", ".join(COMMANDS))
    a = ap.parse_args()
    names = [n for n in a.only.split(",") if n]
    unknown = [n for n in names if n not in COMMANDS]
    if unknown:
        ap.error(f"no such row: {', '.join(unknown)} (rows: {', '.join(COMMANDS)})")
    print("| command | CPU model (default) | `--cpu ideal` | ratio |")
    print("|---|---|---|---|")
    for n in names:
        args = COMMANDS[n]
        model, ideal = [], []
        for _ in range(a.rounds):
            model.append(wall(args))
            ideal.append(wall([*args, "--cpu", "ideal"]))
        m, i = statistics.median(model), statistics.median(ideal)
        print(f"| `rprs {' '.join(args)}` | {m:.2f} s | {i:.2f} s | {m / i:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
