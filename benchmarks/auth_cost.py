"""What the authenticated profile costs on the air (docs/protocol.md §4.11): the same seeded
ring of three children, without and with ``--auth-key``. Prints a Markdown table: the frame
overhead, the largest Content a turn holds, the ring's cycle idle and saturated, and the MAC
efficiency (goodput: Content bytes of delivered messages per second over the channel's 960
bytes/s, saturated) against its bound L / (L + overhead + one ack's 9 bytes + Ttrans in byte
times), for three payload sizes.

    python benchmarks/auth_cost.py [--seconds 40] [--seed 2]
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import statistics

from firmware_model.radio.auth import AUTH_TEXT_LEN, RingKey
from firmware_model.radio.frame import FRAME_OVERHEAD, MAX_CONTENT
from firmware_model.radio.mac import MacConfig
from firmware_model.timing import CHILD_BYTE_TICKS, TICK_HZ, TTRANS_TICKS, s_to_ticks
from hil.sim.world import SimConfig, World

CAPACITY = 960.0                      # bytes/s at 9600 baud, 8N1
TTRANS_BYTES = TTRANS_TICKS / CHILD_BYTE_TICKS
ROBOTS = (1, 2, 3)
KEY = RingKey(bytes(range(16)))       # any key: the cost does not depend on it
START = 10.0                          # s: the ring has formed (and filled, saturated)


def run(auth: bool, seconds: float, seed: int, payload: int | None) -> tuple[float, float]:
    """(the ring's mean cycle in ms, goodput / capacity) from START to the end."""
    evs: list[dict] = []
    w = World(SimConfig(robots=ROBOTS, duration=seconds, seed=seed,
                        load="saturate" if payload else "idle", payload=payload,
                        mac=MacConfig(auth=KEY if auth else None), keep_records=True),
              on_event=evs.append)
    w.run(s_to_ticks(START))
    t0 = w.now
    before = sum(len(o.message.content) for o in w.outcomes if o.delivered)
    w.run()
    after = sum(len(o.message.content) for o in w.outcomes if o.delivered)
    ends = [e["end"] for e in evs if e["ev"] == "frame" and e["src"] == ROBOTS[0]
            and e["end"] >= t0]
    cycle = statistics.mean(b - a for a, b in zip(ends, ends[1:])) / TICK_HZ * 1000
    return cycle, (after - before) / ((w.now - t0) / TICK_HZ) / CAPACITY


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=40.0,
                   help="simulated seconds a run (the first 10 are not measured)")
    p.add_argument("--seed", type=int, default=2)
    a = p.parse_args()
    if a.seconds <= START + 1:
        p.error(f"--seconds must be more than {START + 1:g}")
    rows = [("frame overhead (bytes)", f"{FRAME_OVERHEAD}", f"{FRAME_OVERHEAD + AUTH_TEXT_LEN}"),
            ("largest Content of a child's frame (bytes, clause 14)", f"{MAX_CONTENT}",
             f"{MAX_CONTENT - AUTH_TEXT_LEN}")]
    idle = [run(on, a.seconds, a.seed, None)[0] for on in (False, True)]
    rows.append(("idle cycle of 3 children (ms)", f"{idle[0]:.1f}", f"{idle[1]:.1f}"))
    for size in (8, 100, 498):
        got = [run(on, a.seconds, a.seed, size) for on in (False, True)]
        bound = [size / (size + FRAME_OVERHEAD + ext + 9 + TTRANS_BYTES)
                 for ext in (0, AUTH_TEXT_LEN)]
        rows.append((f"saturated cycle, {size}-byte messages (ms)", f"{got[0][0]:.1f}",
                     f"{got[1][0]:.1f}"))
        rows.append((f"MAC efficiency, {size}-byte messages (goodput / bound with one ack)",
                     f"{got[0][1]:.3f} / {bound[0]:.3f}", f"{got[1][1]:.3f} / {bound[1]:.3f}"))
    print(f"Ring of children {', '.join(map(str, ROBOTS))}, seed {a.seed}, measured over "
          f"{START:g}-{a.seconds:g} s\n")
    print("| figure | without | with `--auth-key` |")
    print("|---|---|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
