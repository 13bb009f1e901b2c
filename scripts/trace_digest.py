"""Digests of the simulator's traces for a fixed set of seeded runs (tests/trace_digests.py).

    python scripts/trace_digest.py            # print them, and say which differ from the record
    python scripts/trace_digest.py --write    # record them (tests/data/trace_digests.txt)

A change meant to leave behaviour alone must leave every digest unchanged
(tests/hil/sim/test_trace_digests.py checks it); record them again only for a change of behaviour
that is meant, and say why in the commit.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    import _needs_project  # noqa: F401    (scripts/ is sys.path[0] here)

import argparse
import importlib.util
import sys
from pathlib import Path

# the runs are test data (tests/trace_digests.py), loaded by its path: tests/ on sys.path would
# shadow the packages it mirrors (tests/firmware_model/, ...)
_spec = importlib.util.spec_from_file_location(
    "trace_digests", Path(__file__).resolve().parent.parent / "tests" / "trace_digests.py")
assert _spec is not None and _spec.loader is not None
_digests = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_digests)
RECORDED, RUNS, digest, read_recorded = (_digests.RECORDED, _digests.RUNS, _digests.digest,
                                         _digests.read_recorded)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--write", action="store_true", help=f"record the digests in {RECORDED}")
    a = p.parse_args()
    recorded = read_recorded() if RECORDED.exists() else {}
    lines, changed = [], 0
    for name, args in RUNS.items():
        h = digest(args)
        lines.append(f"{h}  {name}")
        old = recorded.get(name)
        mark = "" if old == h else ("   (no record)" if old is None else
                                    "   (differs from the record)")
        changed += bool(mark)
        print(f"{h}  {name}{mark}", flush=True)
    if a.write:
        RECORDED.write_text("\n".join(lines) + "\n")
        print(f"recorded in {RECORDED}")
        return 0
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
