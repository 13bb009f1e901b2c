"""Two bench findings in the simulator, as figures (docs/guarantees.md): robot 6's R-stagger
after bursts, and a cut-off Header in every invitation window.

    python benchmarks/stagger_and_cutoff.py stagger [--tslot-ms 80]
        children 1, 2, 6 with the real-time margins (Tslot as given), a 4 ms burst every
        0.73 s for 28 s: the misses each robot counted, drops, robot-robot collisions
    python benchmarks/stagger_and_cutoff.py cutoff [--seconds 37]
        ring 1, 3, 4 (robot 5 absent), every invitation of 5 answered by a Header that
        promises 562 bytes and stops after 12: good frames against the same run without it,
        with the exact and the real-time margins
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
from collections import Counter
from dataclasses import replace

from firmware_model.radio.mac import MacConfig
from firmware_model.timing import TICK_HZ, TTRANS_TICKS
from hil.bench.runner import realtime_config
from hil.sim.faults import parse_fault
from hil.sim.world import SimConfig, World

CUT_OFF = bytes.fromhex("0f0a05373230303330353632")


def stagger(tslot_ms: float) -> None:
    team = (1, 2, 6)
    mac = replace(realtime_config(MacConfig(team=frozenset(team))),
                  tslot=round(tslot_ms * TICK_HZ / 1000))
    faults = tuple(parse_fault(f"burst@{2 + 0.73 * k:.2f}:0.004") for k in range(39))
    evs: list[dict] = []
    World(SimConfig(robots=team, duration=30.0, seed=1, faults=faults, mac=mac),
          on_event=evs.append).run()
    misses = Counter((e["robot"], e["by"]) for e in evs if e["ev"] == "miss")
    print(f"Tslot {tslot_ms:g} ms, 39 bursts of 4 ms in 28 s, children 1, 2, 6:")
    print("  misses (robot, counted by):", dict(sorted(misses.items())) or "none")
    print("  drops:", [(e["robot"], e["by"]) for e in evs if e["ev"] == "disable"] or "none")
    print("  robot-robot collisions:",
          sum(1 for e in evs if e["ev"] == "collision" and -1 not in e["robots"]))


def _good_frames(seconds: float, realtime: bool, attack: bool) -> tuple[int, int]:
    w: World | None = None
    n = {"good": 0, "answers": 0}
    end = (3 + seconds) * TICK_HZ

    def on(e: dict) -> None:
        if e["ev"] != "frame" or not 3 * TICK_HZ <= e["start"] < end:
            return
        if not e["collided"] and not e["aborted"]:
            n["good"] += 1
        if attack and e["src"] == 4 and e["kind"] == "control" and e["len"] == 10:
            n["answers"] += 1               # a poll of robot 5 (the only Content of 10 here)
            w.inject_bytes(CUT_OFF, e["end"] + TTRANS_TICKS)
    mac = MacConfig(team=frozenset((1, 3, 4, 5)))
    w = World(SimConfig(robots=(1, 3, 4, 5), duration=3 + seconds + 1, seed=1,
                        faults=(parse_fault("fail:5@0"),),
                        mac=realtime_config(mac) if realtime else mac), on_event=on)
    w.run()
    return n["good"], n["answers"]


def cutoff(seconds: float) -> None:
    print("| margins | good frames, no attack | good frames, attacked | answers | cut |")
    print("|---|---|---|---|---|")
    for realtime in (False, True):
        base, _ = _good_frames(seconds, realtime, False)
        good, answers = _good_frames(seconds, realtime, True)
        print(f"| {'real time' if realtime else 'exact'} | {base} | {good} | {answers} | "
              f"{1 - good / base:.1%} |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="what", required=True)
    s = sub.add_parser("stagger")
    s.add_argument("--tslot-ms", type=float, default=80.0)
    c = sub.add_parser("cutoff")
    c.add_argument("--seconds", type=float, default=37.0)
    a = p.parse_args()
    if a.what == "stagger":
        stagger(a.tslot_ms)
    else:
        cutoff(a.seconds)


if __name__ == "__main__":
    main()
