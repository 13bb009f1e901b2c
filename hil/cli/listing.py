"""``rprs listing``: the model firmware's handlers as F2MC-16LX instruction listings, and
their cycles (firmware_model/isa): the table of every handler row, one listing instruction by
instruction, or a listing of your own (``--file``) counted the same way."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from .common import UserError


def _rows() -> list[dict]:
    from firmware_model.cycle_costs import DEFAULT_COSTS
    from firmware_model.isa.listing import count
    out = []
    for name, cost in DEFAULT_COSTS.rows():
        if not cost.source.startswith("listing:"):
            continue
        c = count(name)
        out.append({"row": name, "cycles": c.cycles, "worst": c.worst,
                    "instructions": c.instructions, "us": round(c.cycles / 16, 2)})
    return out


def _one(name: str, directory: Path | None) -> dict:
    from firmware_model.isa import cycles
    from firmware_model.isa.listing import LISTINGS, ListingError, count
    try:
        c = count(name, directory or LISTINGS)
    except ListingError as exc:
        raise UserError(str(exc)) from None
    return {"listing": name, "cycles": c.cycles, "worst": c.worst,
            "instructions": c.instructions,
            "steps": [{"instruction": s.text, "form": s.form, "cycles": s.cycles,
                       "worst": s.cycles + s.extra_worst,
                       "source": cycles.FORMS[s.form].source} for s in c.steps]}


def cmd_listing(a: argparse.Namespace) -> int:
    if a.file is not None:
        path = Path(a.file)
        if path.suffix != ".asm":
            raise UserError(f"{path}: a listing is a NAME.asm file")
        if not path.is_file():
            raise UserError(f"no listing {path}")
        doc = _one(path.stem, path.parent)
    elif a.name is not None:
        doc = _one(a.name, None)
    else:
        rows = _rows()
        if a.json:
            print(json.dumps({"rows": rows}, indent=1))
            return 0
        print(f"{'row':<18}{'cycles':>8}{'us':>9}{'worst':>8}{'instructions':>14}")
        for r in rows:
            print(f"{r['row']:<18}{r['cycles']:>8}{r['us']:>9.2f}{r['worst']:>8}"
                  f"{r['instructions']:>14}")
        print("cycles: the listing's path, as the CPU model charges it (firmware_model/isa/"
              "cycles.py: MAME's F2MC-16 core, the manual's rows where at hand); worst: "
              "with every fetch across a word boundary (+2) and every CAN buffer access "
              "waiting 64; 'rprs listing NAME' for one listing")
        return 0
    if a.json:
        print(json.dumps(doc, indent=1))
        return 0
    width = max(len(s["instruction"].strip()) for s in doc["steps"]) if doc["steps"] else 10
    for s in doc["steps"]:
        print(f"{s['instruction'].strip():<{width}}  {s['cycles']:>3}  {s['source']}")
    print(f"{doc['listing']}: {doc['cycles']} cycles ({doc['cycles'] / 16:.2f} us at 16 MHz), "
          f"{doc['instructions']} instructions; worst {doc['worst']}")
    return 0


def add(sub) -> None:
    p = sub.add_parser("listing", help="the firmware's handlers as F2MC-16LX instruction "
                       "listings and their cycles")
    p.add_argument("name", nargs="?", metavar="NAME", help="one listing, instruction by "
                   "instruction (uart_rx_byte, can_rx, ...); none: every handler row")
    p.add_argument("--file", metavar="FILE.asm", help="count a listing of your own (its "
                   ".include names files beside it)")
    p.add_argument("--json", action="store_true", help="JSON on stdout")
    p.set_defaults(func=cmd_listing)
