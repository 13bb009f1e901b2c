"""The rotational MAC against its limits: goodput, the cost of a silent robot, failure
detection and rejoin times.

    python benchmarks/mac_efficiency.py [--quick]

Goodput = Content bytes of delivered messages per second over the channel's capacity
(9600 baud 8N1 = 960 bytes/s), saturated, for payload sizes and ring sizes; the analytic
bound for this frame format is L / (L + 14 + Ttrans/byte) (overhead 14 bytes and the 5 ms
switch every turn, 4.81 byte times), and L / (L + 14 + 9 + 4.81) with one piggybacked
acknowledgement (9 bytes) a frame, which is what a saturated ring with random destinations
carries on average. Prints Markdown tables.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import statistics

from firmware_model.radio.mac import MacConfig
from firmware_model.timing import CHILD_BYTE_TICKS, TICK_HZ, TTRANS_TICKS, s_to_ticks
from hil.sim.faults import Fault
from hil.sim.world import SimConfig, World

CAPACITY = 960.0                      # bytes/s at 9600 baud, 8N1
TTRANS_BYTES = TTRANS_TICKS / CHILD_BYTE_TICKS


def goodput(robots, payload: int, seconds: float) -> float:
    w = World(SimConfig(robots=robots, duration=seconds, load="saturate", payload=payload,
                        keep_records=True))
    w.run(s_to_ticks(10.0))                       # the ring has formed and filled
    t0 = w.now
    before = sum(len(o.message.content) for o in w.outcomes if o.delivered)
    w.run()
    after = sum(len(o.message.content) for o in w.outcomes if o.delivered)
    return (after - before) / ((w.now - t0) / TICK_HZ) / CAPACITY


def silent_robot(n: int, runs: int) -> tuple[float, float, float]:
    """Seconds from robot 2's radio failing to its drop: the median and the worst of ``runs``
    failure instants, and docs/protocol.md §7.3's worst case for the ring."""
    robots = tuple(range(1, n + 1))
    out = []
    for k in range(runs):
        at = 6.0 + 0.0377 * k
        evs: list[dict] = []
        w = World(SimConfig(robots=robots, duration=at + 10.0,
                            faults=(Fault("fail", 2, at),)), on_event=evs.append)
        w.run()
        drops = [e["t"] for e in evs if e["ev"] == "disable" and e["robot"] == 2]
        out.append(min(drops) / TICK_HZ - at)
    # worst case: a failure that cuts a frame before its Length, closed a stall gap and a quiet
    # gap later, the next robot's R-stagger, three rounds of ring(mask) frames and Tmax each
    bound = MacConfig(team=frozenset(robots)).silent_drop_ticks(robots) / TICK_HZ
    return statistics.median(out), max(out), bound


def rejoin(n: int, runs: int) -> float:
    robots = tuple(range(1, n + 1))
    out = []
    for k in range(runs):
        rec = 14.0 + 0.0411 * k
        evs: list[dict] = []
        w = World(SimConfig(robots=robots, duration=rec + 20.0,
                            faults=(Fault("fail", 2, 6.0), Fault("recover", 2, rec))),
                  on_event=evs.append)
        w.run()
        back = [e["t"] for e in evs if e["ev"] == "rejoin" and e["robot"] == 2]
        out.append(min(back) / TICK_HZ - rec)
    return statistics.median(out)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    a = p.parse_args()
    secs = 40.0 if a.quick else 120.0
    sizes = (8, 40, 100, 200, 400, 498) if not a.quick else (8, 100, 498)
    rings = (2, 3, 5, 7) if not a.quick else (2, 7)
    print("Goodput / capacity (saturated; bound: frame format alone / with one ack a frame)\n")
    print("| payload (bytes) | bound | bound with ack | " +
          " | ".join(f"{n} robots" for n in rings) + " |")
    print("|---|---|---|" + "---|" * len(rings))
    for L in sizes:
        b = L / (L + 14 + TTRANS_BYTES)
        b2 = L / (L + 14 + 9 + TTRANS_BYTES)
        vals = []
        for n in rings:
            robots = tuple(range(0, n)) if n == 7 else tuple(range(1, n + 1))
            vals.append(goodput(robots, L, secs))
        print(f"| {L} | {b:.3f} | {b2:.3f} | " + " | ".join(f"{v:.3f}" for v in vals) + " |",
              flush=True)
    runs = 3 if a.quick else 7
    print(f"\nA silent robot: time from robot 2's radio failing to its drop ({runs} runs)\n")
    print("| ring | median (s) | worst (s) | worst-case bound (s) | "
          "rejoin after recovery, median (s) |")
    print("|---|---|---|---|---|")
    for n in (3, 4, 6):
        m, worst, bound = silent_robot(n, runs)
        r = rejoin(n, runs)
        print(f"| {n} | {m:.3f} | {worst:.3f} | {bound:.3f} | {r:.3f} |", flush=True)


if __name__ == "__main__":
    main()
