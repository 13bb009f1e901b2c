"""Seeded failovers of the father's PC pair, checked message by message (docs/guarantees.md,
"Open ... the father pair").

    python benchmarks/father_pair.py [--seeds 0-199] [--duration 20] [--cpu estimated]

Each seed runs ``rprs sim --father-standby --checksum --load 1`` on a ring of three (odd seeds)
or four robots with one fault on ID 0 drawn from the seed: every third seed a steal of its turn
at 3-15 s, the others its radio failing at 3-15 s and recovering 0.2-3 s later. For every
message a child sent the father, the trace says whether the sender ended it ``delivered`` and
how many ``deliver`` events (either PC's) it had:

* **acknowledged, delivered by neither PC**: the sender was told ``delivered``, nobody
  delivered it (clause 50: no PC acknowledges what it did not deliver);
* **delivered twice**: both PCs delivered it.

And for every message of the father's (either PC's, ``"pc": 2`` on PC2's events) that ended
``delivered``, whether a frame of the PC that sent it delivered it: **acknowledged, delivered
from no frame of its PC** is one told ``delivered`` by the acknowledgement of the other PC's
message of the same Number (clause 50: the pair shares ID 0's Numbers). A delivery at a
child is the frame's of its Number whose End is nearest: at that End's tick on the ideal CPU
(the default, as ``SimConfig``'s), within a byte of it on the CPU model (``--cpu
estimated``, the command line's default), where frames of one Number are a turn apart.

Messages are told apart by (Source, Number) within a run: a 20 s run sends far fewer than 99
messages a child, so no Number wraps.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import bisect
import random

RANGE_HELP = "seeds as FIRST-LAST (inclusive)"


def faults_for(seed: int) -> tuple:
    """The seed's ring and its one fault on ID 0."""
    from hil.sim.faults import Fault
    rnd = random.Random(seed)
    ring = (0, 1, 2) if seed % 2 else (0, 1, 2, 3)
    if seed % 3 == 0:
        return ring, (Fault("steal", 0, round(rnd.uniform(3, 15), 3)),)
    a = round(rnd.uniform(3, 15), 3)
    return ring, (Fault("fail", 0, a), Fault("recover", 0, round(a + rnd.uniform(0.2, 3), 3)))


def check(events: list[dict]) -> dict[str, int]:
    """Messages from children to the father in one run's events: how many ended
    ``delivered``, how many of those no PC delivered, and deliveries beyond the first."""
    deliveries: dict[tuple[int, int], int] = {}
    acked = lost = 0
    for e in events:
        ev = e["ev"]
        if ev == "submit" and e["src"] != 0 and e["dst"] == 0:
            deliveries[(e["src"], e["num"])] = 0
        elif ev == "deliver" and e["to"] == 0 and (e["src"], e["num"]) in deliveries:
            deliveries[(e["src"], e["num"])] += 1
        elif ev == "delivered" and e["src"] != 0 and (e["src"], e["num"]) in deliveries:
            acked += 1
            lost += deliveries[(e["src"], e["num"])] == 0
    twice = sum(n - 1 for n in deliveries.values() if n > 1)
    return {"acknowledged": acked, "lost": lost, "twice": twice, **_fathers(events)}


def _fathers(events: list[dict]) -> dict[str, int]:
    """The father's messages that ended ``delivered``, and those of them no frame of the PC
    that sent them delivered (to their destination, or to anyone for a broadcast)."""
    ends: dict[int, list[int]] = {}               # Number -> Ends of ID 0's frames, in order
    pcs: dict[tuple[int, int], set[int]] = {}     # (End, Number) -> PCs whose frame ended then
    for e in events:
        if e["ev"] == "frame" and e["src"] == 0:
            if (e["t"], e["num"]) not in pcs:
                ends.setdefault(e["num"], []).append(e["t"])
            pcs.setdefault((e["t"], e["num"]), set()).add(e.get("pc", 1))
    given = set()
    for e in events:
        if e["ev"] == "deliver" and e["src"] == 0 and e["num"] in ends:
            # the frame whose End is nearest: the End byte's handler runs at its RDRF, before
            # the stop bit ends, on the CPU model; frames of one Number are a turn apart
            near = ends[e["num"]]
            k = bisect.bisect_left(near, e["t"])
            end = min(near[max(k - 1, 0):k + 1], key=lambda x: abs(x - e["t"]))
            given |= {(pc, e["num"], e["to"]) for pc in pcs[(end, e["num"])]}
    told = [(e.get("pc", 1), e["num"], e["dst"]) for e in events
            if e["ev"] == "delivered" and e["src"] == 0]
    unsent = sum(not any(g[:2] == (pc, num) and dst in (g[2], 7) for g in given)
                 for pc, num, dst in told)
    return {"father_acknowledged": len(told), "father_unsent": unsent}


def run(seed: int, duration: float, cpu: str = "ideal") -> dict[str, int]:
    from firmware_model.cycle_costs import DEFAULT_COSTS
    from firmware_model.radio.mac_config import MacConfig
    from hil.sim.world import SimConfig, World
    ring, faults = faults_for(seed)
    events: list[dict] = []
    World(SimConfig(robots=ring, duration=duration, seed=seed, load=1.0, father_standby=True,
                    mac=MacConfig(checksum=True), faults=faults,
                    cpu=DEFAULT_COSTS if cpu == "estimated" else None),
          on_event=events.append).run()
    return check(events)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0-199", help=RANGE_HELP)
    ap.add_argument("--duration", type=float, default=20.0, help="simulated s a run")
    ap.add_argument("--cpu", choices=("ideal", "estimated"), default="ideal",
                    help="the CPU of the children and PCs: the ideal one (the default, as "
                    "docs/guarantees.md's table) or the CPU model")
    a = ap.parse_args()
    try:
        first, last = (int(x) for x in a.seeds.split("-"))
    except ValueError:
        ap.error(f"--seeds {a.seeds!r}: {RANGE_HELP}, e.g. 0-199")
    total = {"acknowledged": 0, "lost": 0, "twice": 0, "father_acknowledged": 0,
             "father_unsent": 0}
    bad = []
    for seed in range(first, last + 1):
        r = run(seed, a.duration, a.cpu)
        for k in total:
            total[k] += r[k]
        if r["lost"] or r["twice"] or r["father_unsent"]:
            bad.append(f"{seed} (lost {r['lost']}, twice {r['twice']}, the father's "
                       f"unsent {r['father_unsent']})")
    n = last - first + 1
    print("| seeded father-pair runs | messages to the father acknowledged | acknowledged, "
          "delivered by neither PC | delivered twice | the father's messages acknowledged | "
          "acknowledged, delivered from no frame of its PC | runs with any |")
    print("|---|---|---|---|---|---|---|")
    print(f"| {n} (seeds {first}-{last}, {a.duration:g} s) | {total['acknowledged']:,} | "
          f"{total['lost']} | {total['twice']} | {total['father_acknowledged']:,} | "
          f"{total['father_unsent']} | {len(bad)} |")
    if bad:
        print("\nruns: " + ", ".join(bad))


if __name__ == "__main__":
    main()
