"""The cycle-cost table of the child firmware on the MB90F549: every figure the CPU model
(firmware_model/mcu/cpu.py) charges, where it comes from, and the range it is good for.

One machine cycle is one 62.5 ns tick at 16 MHz. The robots' firmware is not published, so a
handler's body is the model firmware's own: written as an F2MC-16LX instruction listing, one
path through the handler, and counted. Three kinds of source, named in each row:

* ``manual``: F2MC-16LX hardware manuals, "Interrupts" (MB90420/5 §6.4.5; MB90560 §6.7,
  Table 6.7-3) and the instruction tables (MB90560 Appendix B, Table B.8-6).
* ``listing``: a handler body or a routine of the float library (the MB90F549 has no FPU:
  C ``float`` runs in software; the routines are IEEE single, the transcendental ones
  composed of the others as the algorithm each header names makes its calls, charged for
  the operands of avr-libc's benchmark, whose 8-bit figures each row quotes),
  ``firmware_model/isa/listings/NAME.asm`` summed by
  firmware_model/isa/listing.py from the instruction table firmware_model/isa/cycles.py
  (each form's cycles from MAME's F2MC-16 core, checked against the manual's rows where they
  are at hand). Exact for that listing and path; its worst case (fetch and CAN buffer waits)
  is in the row's range.
* ``estimate``: one SHA-256 compression, scaled from a published figure on another core.

Change any row with ``--cpu-costs FILE`` (TOML: ``name = cycles`` under ``[costs]``, or
``name = "mine.asm"`` under ``[listings]`` for a listing of your own);
``rprs sim --cpu-report`` prints the table in use with the load it caused.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, fields, replace
from pathlib import Path

from .isa.listing import Count, ListingError, count


@dataclass(frozen=True)
class Cost:
    """One row: ``cycles`` (machine cycles), where the figure comes from, its valid range, and
    ``worst_extra``: the cycles its worst case adds (a listing's program-fetch and CAN buffer
    waits, which the CPU model does not charge; 0 for a figure given whole)."""

    cycles: int
    source: str
    good_for: str
    worst_extra: int = 0


def listing_cost(c: Count, file: str, note: str, path: str = "that path") -> Cost:
    """A row from a listing's count (firmware_model/isa/listing.py): its ``file``, its
    instructions and ``note``; good for ``path`` (the path or operands it charges)."""
    return Cost(c.cycles, f"listing: {file}, {c.instructions} instructions{note}",
                f"{path}; worst {c.worst} with fetch and CAN buffer waits", c.worst - c.cycles)


def _listed(name: str, note: str = "", path: str = "that path") -> Cost:
    """The row of the model firmware's listing ``name``."""
    return listing_cost(count(name), f"firmware_model/isa/listings/{name}.asm",
                        f", cycles from firmware_model/isa/cycles.py{note}", path)


@dataclass(frozen=True)
class CycleCosts:
    """Every cost the firmware model charges (machine cycles)."""

    # -- the core (manual) --------------------------------------------------------------
    entry: Cost = Cost(24, "manual: interrupt start 24 + 6 x Z, Z = 0 (stack in internal RAM "
                       "at an even address; Z = +2 odd, +1..+4 external)", "exact for Z = 0")
    reti: Cost = Cost(11, "manual: RETI 11 + 6 x Z, Z = 0", "exact for Z = 0")
    sample_wait_max: Cost = Cost(45, "manual: a request is sampled in an instruction's last "
                                 "cycle; the longest is POPW RW0-RW7, 45 cycles",
                                 "worst case; not simulated, added in the report")
    mul16: Cost = Cost(11, "manual: Table B.8-6, MULUW A, word x word, non-zero", "exact")
    div32: Cost = Cost(22, "manual: Table B.8-6, DIVUW A,ear, long / word, normal", "exact")

    # -- soft-float (listing: the model firmware's float library, counted) --------------------
    f_add: Cost = _listed("f_add", " (avr-libc's 8-bit figure: 108)", "1.234 + 5.678")
    f_mul: Cost = _listed("f_mul", " (avr-libc: 138)", "1.234 x 5.678")
    f_div: Cost = _listed("f_div", " (avr-libc: 465)", "1.234 / 5.678")
    f_sin: Cost = _listed("f_sin", " (avr-libc: 1653)", "sin(1.2345)")
    f_cos: Cost = _listed("f_cos", " (avr-libc: 1671)", "cos(1.2345)")
    f_atan2: Cost = _listed("f_atan2", " (avr-libc: 2857)", "atan2(1.234, 5.678)")
    f_acos: Cost = _listed("f_acos", " (avr-libc: 2455)", "acos(0.54321)")
    f_hypot: Cost = _listed("f_hypot", " (avr-libc: 866)", "hypot(1.234, 5.678)")
    f_round: Cost = _listed("f_round", " (avr-libc: 150)", "round(1.2345)")

    # -- handler bodies (listing: firmware_model/isa/listings/NAME.asm, counted) -----------
    uart_rx_byte: Cost = _listed("uart_rx_byte")
    mac_frame: Cost = _listed("mac_frame")
    mac_timer: Cost = _listed("mac_timer")
    uart_tx_byte: Cost = _listed("uart_tx_byte")
    uart_tx_done: Cost = _listed("uart_tx_done")
    content_byte: Cost = _listed("content_byte")
    command: Cost = _listed("command")
    can_frame_out: Cost = _listed("can_frame_out", "; its scaling, 2 MULUW and a DIVUW, is "
                                  "charged from those rows")
    can_rx: Cost = _listed("can_rx")
    can_tx: Cost = _listed("can_tx")
    can_status: Cost = _listed("can_status")
    sha256_block: Cost = Cost(75_000, "estimate: one SHA-256 compression (64 rounds of 32-bit "
                              "adds, rotations and logic), scaled from a published figure: "
                              "SHA-512's compression in hand-written MSP430 assembler takes "
                              "40.6k cycles on an MSP430F1611, the fastest C 2.3x that "
                              "(C. Franck, J. Grossschaedl, SecITC 2021); SHA-256 has words "
                              "half as wide and 64 rounds, not 80: 0.4x, 16k (asm) or 37k "
                              "(C) on the MSP430; the F2MC-16LX's long-word instructions take "
                              "2-8 cycles where the MSP430's register moves take 1-2: 2x, "
                              "75k cycles (4.7 ms) compiled C", "0.5x-2x")
    dispatcher_timer: Cost = _listed("dispatcher_timer")

    def names(self) -> list[str]:
        return [f.name for f in fields(self)]

    def rows(self) -> list[tuple[str, Cost]]:
        return [(f.name, getattr(self, f.name)) for f in fields(self)]


DEFAULT_COSTS = CycleCosts()

FORWARD_OPS = {"f_sin": 4, "f_cos": 4, "f_mul": 13, "f_add": 8}
"""Soft-float operations of kinematics.forward: 4 degree-to-radian scalings, 8 products and
the pitch back to degrees (13 multiplications); sin and cos of q1 and of the three link
angles; 8 sums (3 angle sums, 2 for r, 3 for z)."""

INVERSE_OPS = {"f_hypot": 1, "f_atan2": 5, "f_sin": 3, "f_cos": 3, "f_acos": 2, "f_mul": 18,
               "f_add": 18, "f_div": 1, "f_round": 8}
"""Soft-float operations of kinematics.inverse in its worst case (elbow up refused, elbow
down taken): hypot, atan2 and a degree conversion for the base yaw; the pitch to radians,
its cos and sin for the wrist point (2 products, 3 sums); the cosine rule with its
constants folded (2 products, 3 sums, 1 division); per elbow choice an acos, two atan2, a
sin and a cos, 6 products (3 degree conversions among them), 6 sums and 4 roundings.
Comparisons (limits, the acos domain) are not counted."""


def ops_cycles(ops: dict[str, int], costs: CycleCosts = DEFAULT_COSTS) -> int:
    """Machine cycles of a count of soft-float operations."""
    return sum(n * getattr(costs, name).cycles for name, n in ops.items())


def load_costs(path: str | Path, base: CycleCosts = DEFAULT_COSTS) -> CycleCosts:
    """``base`` with the rows a TOML file sets: ``name = cycles`` under ``[costs]``, or
    ``name = "FILE.asm"`` under ``[listings]``, a listing of your own counted as the handler
    rows are (firmware_model/isa/listing.py; FILE relative to the TOML file). Raises
    ValueError with the file, the row and what is wrong."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:                                # Python 3.10
        import tomli as tomllib
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"cannot read the cost table {p}: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{p} is not TOML: {exc}") from None
    table = data.get("costs", {})
    listed = data.get("listings", {})
    if not isinstance(table, dict) or not isinstance(listed, dict) or not (table or listed):
        raise ValueError(f"{p}: put the rows under a [costs] table, e.g. "
                         f"[costs]\\nuart_rx_byte = 200, or listings under [listings], e.g. "
                         f"[listings]\\nuart_rx_byte = \"mine.asm\"")
    known = set(base.names())
    changes = {}
    for name, value in table.items():
        if name not in known:
            raise ValueError(f"{p}: no cost named {name!r}; the rows are "
                             f"{', '.join(sorted(known))}")
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ValueError(f"{p}: {name} must be a whole number of cycles >= 0, "
                             f"got {value!r}")
        old = getattr(base, name)
        changes[name] = Cost(value, f"{p.name} (was {old.cycles}: {old.source})", "as given")
    for name, value in listed.items():
        if name not in known:
            raise ValueError(f"{p}: no cost named {name!r}; the rows are "
                             f"{', '.join(sorted(known))}")
        if name in changes:
            raise ValueError(f"{p}: {name} is set under [costs] and under [listings]")
        if not isinstance(value, str) or not value.endswith(".asm"):
            raise ValueError(f"{p}: [listings] {name} must name a listing, "
                             f"\"FILE.asm\", got {value!r}")
        asm = p.parent / value
        try:
            c = count(asm.stem, asm.parent)
        except ListingError as exc:
            raise ValueError(f"{p}: [listings] {name}: {exc}") from None
        old = getattr(base, name)
        changes[name] = listing_cost(c, value, f" (was {old.cycles}: {old.source})")
    return replace(base, **changes)


def body_cycles(costs: CycleCosts, *terms: tuple[str, int | float]) -> int:
    """Sum of ``count x row`` terms, rounded up to whole cycles."""
    return math.ceil(sum(getattr(costs, name).cycles * n for name, n in terms))


DRIVE_OPS_PER_JOINT = {"f_add": 3, "f_div": 2, "f_round": 2, "f_mul": 1}
"""Soft-float operations of the coordinated-motion plan per moving joint
(dispatcher._drive_joints): the distance and its time at rated speed, the joint's speed,
its rounding, and the deadline's scaling."""

_MOVES = ("movex", "movey", "movez", "moveto")


def frame_out_cycles(costs: CycleCosts = DEFAULT_COSTS) -> int:
    """One CAN command frame written: packing plus the integer scaling of its signals (the
    angle and speed to their raw units: two multiplications and a division)."""
    return costs.can_frame_out.cycles + 2 * costs.mul16.cycles + costs.div32.cycles


def message_cycles(commands, costs: CycleCosts = DEFAULT_COSTS) -> int:
    """Main-loop cycles to parse and act on one delivered message: the Content parser per
    byte, each command's dispatch, the arm kinematics of a move (forward then inverse, in
    soft-float), the motion plan per joint and the CAN frames written."""
    out = frame_out_cycles(costs)
    total = 0
    for c in commands:
        total += len(c.text()) * costs.content_byte.cycles + costs.command.cycles
        name = c.name
        if name in _MOVES:
            total += ops_cycles(FORWARD_OPS, costs) + ops_cycles(INVERSE_OPS, costs)
            total += 4 * (ops_cycles(DRIVE_OPS_PER_JOINT, costs) + out)
        elif name == "act":
            total += 4 * (ops_cycles(DRIVE_OPS_PER_JOINT, costs) + out)
        elif name == "joint":
            total += ops_cycles(DRIVE_OPS_PER_JOINT, costs) + out
        elif name in ("wheel", "paw"):
            total += out
        elif name == "stop":
            total += 5 * out
        elif name == "status":
            total += 60 * costs.content_byte.cycles       # formatting a ~60-byte reply
    return total


def markdown_table(costs: CycleCosts = DEFAULT_COSTS) -> str:
    """The table as docs/cpu.md shows it (a test keeps the two the same)."""
    lines = ["| row | cycles | us | source | good for |", "|---|---:|---:|---|---|"]
    for name, c in costs.rows():
        lines.append(f"| `{name}` | {c.cycles} | {c.cycles / 16:.2f} | {c.source} | "
                     f"{c.good_for} |")
    return "\n".join(lines)
