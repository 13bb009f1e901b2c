"""Full lock-step search: every burst length 1-600 bytes at every byte offset of an idle cycle,
for rings of 2-7 robots with and without the father (hil/sim/lockstep.py; docs/guarantees.md).

    python scripts/lockstep_search.py [--lengths 1-600] [--rings 1,2 0,1,2 ...]
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    import _needs_project  # noqa: F401    (scripts/ is sys.path[0] here)

import argparse
import sys
import time

from hil.sim.lockstep import search


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lengths", default="1-600", help="burst lengths in bytes, A-B")
    ap.add_argument("--rings", nargs="*", help="rings as comma-separated IDs")
    a = ap.parse_args(argv)
    lo, _, hi = a.lengths.partition("-")
    lengths = range(int(lo), int(hi or lo) + 1)
    rings = [tuple(int(x) for x in r.split(",")) for r in a.rings] if a.rings else \
        [tuple(range(1, n + 1)) for n in range(2, 7)] + [tuple(range(0, n)) for n in range(2, 8)]
    bad_total = cases = 0
    for robots in rings:
        t = time.time()
        verdicts = search(robots, lengths)
        bad = [v for v in verdicts if not v.ok]
        worst = max((v.resume_ticks or 0) for v in verdicts)
        cases += len(verdicts)
        bad_total += len(bad)
        print(f"ring {robots}: {len(verdicts)} cases, {len(bad)} bad, longest resume "
              f"{worst / 16_000:.1f} ms (bound {verdicts[0].bound_ticks / 16_000:.1f} ms), "
              f"{time.time() - t:.0f} s", flush=True)
        for v in bad[:5]:
            print("   ", v)
    print(f"{cases} cases, {bad_total} bad")
    return 1 if bad_total else 0


if __name__ == "__main__":
    sys.exit(main())
