"""What the opt-in checksum buys (docs/mac.md): the same seeded ring and load, with and without
``crc()``, under the same byte error rates. Prints a Markdown table.

    python benchmarks/checksum_effect.py [--seed 3] [--robots 0,1,2,3,4]
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse

from firmware_model.radio.mac import MacConfig
from hil.sim.world import SimConfig, World


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=3)
    p.add_argument("--robots", default="0,1,2,3,4")
    p.add_argument("--bers", default="1e-3,5e-3,1e-2")
    a = p.parse_args()
    robots = tuple(int(x) for x in a.robots.split(","))
    print("| BER | checksum | submitted | delivered | failed | corrupted deliveries | "
          "duplicate deliveries |")
    print("|---|---|---|---|---|---|---|")
    for ber in (float(b) for b in a.bers.split(",")):
        for ck in (False, True):
            w = World(SimConfig(robots=robots, duration=120.0, seed=a.seed, ber=ber, load=2.0,
                                load_until=45.0, mac=MacConfig(checksum=ck)))
            w.run()
            s = w.summary()
            print(f"| {ber:g} | {'on' if ck else 'off (paper)'} | {s['submitted']} | "
                  f"{s['delivered']} | {s['failed']} | {s['corrupt_deliveries']} | "
                  f"{s['duplicate_deliveries']} |")


if __name__ == "__main__":
    main()
