"""F2MC-16LX instruction listings and their cycle count: the model firmware's handlers as the
instructions they run, summed from the instruction table (:mod:`firmware_model.isa.cycles`).

A listing (``firmware_model/isa/listings/NAME.asm``) is one path through one handler, the path
the CPU model charges on every call. Its syntax is this project's, close to Fujitsu's
assembler:

* one instruction a line, ``MNEMONIC operand, operand``; ``;`` starts a comment; a line that
  ends in ``:`` is a label;
* operands: ``A``, ``SP``, ``ILM``, ``RP``, ``CCR``; registers ``R0``-``R7``, ``RW0``-``RW7``,
  ``RL0``-``RL3``; ``#value``; ``I:name`` an I/O register (0000-00FF, io addressing),
  ``S:name`` a variable in the direct page (dir), a bare name a 16-bit address (addr16);
  ``I:name:bit``, ``S:name:bit`` and ``name:bit`` a bit; ``@RWj``, ``@RWj+``, ``@RWi+disp8``,
  ``@RWj+disp16``, ``@RW0+RW7``, ``@RW1+RW7``, ``@PC+disp16`` the ea modes; a list
  ``(RW0,RW1)`` for PUSHW/POPW; a label for a branch;
* a conditional branch says which way the path goes: ``{taken}`` or ``{not taken}``;
* a shift by a count in R0 says the count: ``{bits N}``;
* ``{can}`` marks an access to a CAN message buffer, which may wait while the controller uses
  it (counted in the worst case only);
* ``.repeat N`` ... ``.endr`` runs the lines between N times; ``.include NAME`` counts another
  listing in place (a shared routine).

:func:`count` gives the cycles the CPU model charges (each instruction's figure for its
form and addressing mode, operands in internal RAM at even addresses or I/O registers: no
access correction) and the worst case (every instruction fetched across a word boundary,
every CAN buffer access waiting its longest).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import NamedTuple

from . import cycles as table

LISTINGS = Path(__file__).with_name("listings")

_REG8 = re.compile(r"R[0-7]$")
_REG16 = re.compile(r"RW[0-7]$")
_REG32 = re.compile(r"RL[0-3]$")
_EA = (
    (re.compile(r"@RW[0-3]\+$"), "@RWj+"),
    (re.compile(r"@RW[0-7]\+(?:0x[0-9A-Fa-f]+|\d+)$"), "@RWi+disp8"),
    (re.compile(r"@RW[0-3]\+disp16:\S+$"), "@RWj+disp16"),
    (re.compile(r"@RW[01]\+RW7$"), "@RW0+RW7"),
    (re.compile(r"@PC\+\S+$"), "@PC+disp16"),
    (re.compile(r"@RW[0-3]$"), "@RWj"),
)
_SPECIAL = {"A", "SP", "ILM", "RP", "CCR", "PCB", "DTB", "ADB", "DPR", "USB", "SSB"}


class ListingError(ValueError):
    """A listing the counter cannot read: the file, the line and what is wrong."""


@dataclass(frozen=True)
class Step:
    """One instruction of a listing as counted: the line, its form in the instruction table,
    its cycles (machine cycles), the worst case's extra cycles, and the shift count it is
    charged for (``{bits N}``; None for a form without one)."""

    text: str
    form: str
    cycles: int
    extra_worst: int
    bits: int | None = None


class Line(NamedTuple):
    """An instruction line of an expanded listing: its file, line number, text (comment
    stripped) and the labels just above it (after the previous instruction or include)."""

    file: str
    no: int
    text: str
    labels: frozenset[str]


@dataclass
class Count:
    """A listing's sum: ``cycles`` (what the CPU model charges), ``worst`` (with the fetch and
    CAN-buffer waits), ``instructions`` (executed, repeats counted) and each step."""

    name: str
    cycles: int = 0
    worst: int = 0
    instructions: int = 0
    steps: list[Step] = field(default_factory=list)

    def add(self, step: Step) -> None:
        self.cycles += step.cycles
        self.worst += step.cycles + step.extra_worst
        self.instructions += 1
        self.steps.append(step)


def operand_kind(op: str) -> str:
    """The operand's kind as the instruction table names it (``A``, ``#imm``, ``Ri``,
    ``RWi``, ``RLi``, ``io``, ``dir``, ``addr16``, ``io:bp``, ``dir:bp``, ``rlst``, ``rel``
    or an ea mode such as ``@RWi+disp8``)."""
    if op in _SPECIAL:
        return op
    if op.startswith("#"):
        return "#imm"
    if _REG8.match(op):
        return "Ri"
    if _REG16.match(op):
        return "RWi"
    if _REG32.match(op):
        return "RLi"
    if op.startswith("("):
        return "rlst"
    if op == "@A":
        return op
    if op.startswith("@"):
        for pattern, mode in _EA:
            if pattern.match(op):
                return mode
        raise ValueError(f"no addressing mode {op!r}")
    if op.startswith(("I:", "S:")):
        kind = "io" if op[0] == "I" else "dir"
        return kind + ":bp" if op.count(":") == 2 else kind
    if re.match(r"[A-Za-z_]\w*:[0-7]$", op):
        return "addr16:bp"
    if re.match(r"[A-Za-z_.][\w.]*$", op):
        return "name"          # a label or a 16-bit address: the instruction decides
    raise ValueError(f"cannot read the operand {op!r}")


def _form(mnemonic: str, kinds: list[str]) -> str:
    """The instruction table's key for ``mnemonic`` with these operand kinds: a bare name is
    a branch target (``rel``) where the table has that form, else a 16-bit address."""
    for choice in ("rel", "addr16"):
        key = f"{mnemonic} {','.join(choice if k == 'name' else k for k in kinds)}".strip()
        if key in table.FORMS or "name" not in kinds:
            return key
    return key


def split_line(line: str) -> tuple[str, list[str], set[str]]:
    """An instruction line's mnemonic (upper case), operands and ``{...}`` notes."""
    notes = set(n.strip() for n in re.findall(r"\{([^}]*)\}", line))
    line = re.sub(r"\{[^}]*\}", "", line).strip()
    if " " not in line:
        return line.upper(), [], notes
    mnemonic, rest = line.split(None, 1)
    ops, depth, cur = [], 0, ""
    for ch in rest:
        if ch == "," and depth == 0:
            ops.append(cur.strip())
            cur = ""
            continue
        depth += ch == "("
        depth -= ch == ")"
        cur += ch
    ops.append(cur.strip())
    return mnemonic.upper(), [o for o in ops if o], notes


@lru_cache(maxsize=None)
def step(text: str) -> Step:
    """One instruction line as counted (a pure function of the line and the table: cached,
    as repeats and includes count the same lines many times). ValueError says what is
    wrong with it."""
    mnemonic, ops, notes = split_line(text)
    kinds = [operand_kind(o) for o in ops]
    key = _form(mnemonic, kinds)
    form = table.FORMS.get(key)
    if form is None:
        raise ValueError(f"{key!r} is not in the instruction table "
                         f"(firmware_model/isa/cycles.py)")
    conditional = form.taken is not None
    if conditional and not notes & {"taken", "not taken"}:
        raise ValueError(f"{mnemonic} is a conditional branch: say {{taken}} or {{not taken}}")
    if not conditional and notes & {"taken", "not taken"}:
        raise ValueError(f"{mnemonic} is no conditional branch")
    n = form.taken if "taken" in notes and form.taken is not None else form.cycles
    bits = [note[5:].strip() for note in notes if note.startswith("bits ")]
    count_bits = None
    if form.per_bit:
        if len(bits) != 1 or not bits[0].isdigit():
            raise ValueError(f"{mnemonic} shifts by a count: say {{bits N}}")
        count_bits = int(bits[0])
        n += form.per_bit * count_bits
    elif bits:
        raise ValueError(f"{mnemonic} takes no {{bits N}}")
    if form.per_register:
        regs = [r for r in ops[-1].strip("()").split(",") if r.strip()]
        n += form.per_register * len(regs)
    extra = table.FETCH_WORST
    if "can" in notes:
        extra += table.CAN_BUFFER_WAIT_MAX
    return Step(text, key, n, extra, count_bits)


def expand(name: str, directory: Path = LISTINGS, seen: tuple[str, ...] = ()) -> list[Line]:
    """The listing's instruction lines in the order its path runs them: includes expanded,
    repeats unrolled."""
    if name in seen:
        raise ListingError(f"{name}.asm includes itself through {' -> '.join(seen)}")
    path = directory / f"{name}.asm"
    try:
        raw = path.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise ListingError(f"no listing {path.name}: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ListingError(f"listing {path}: not UTF-8 text (byte {exc.start})") from None
    out: list[Line] = []
    stack: list[tuple[int, list[Line]]] = []
    labels: set[str] = set()
    for no, line in enumerate(raw, 1):
        text = line.split(";", 1)[0].strip()
        if text.endswith(":"):
            labels.add(text[:-1].strip())
        if not text or text.endswith(":"):
            continue
        target = stack[-1][1] if stack else out
        word = text.split()[0].lower()
        if word == ".repeat":
            try:
                times = int(text.split()[1])
            except (IndexError, ValueError):
                raise ListingError(f"{path.name}:{no}: .repeat needs a count") from None
            stack.append((times, []))
        elif word == ".endr":
            if not stack:
                raise ListingError(f"{path.name}:{no}: .endr without .repeat")
            times, body = stack.pop()
            (stack[-1][1] if stack else out).extend(body * times)
        elif word == ".include":
            target.extend(expand(text.split()[1], directory, seen + (name,)))
            labels = set()
        else:
            target.append(Line(path.name, no, text, frozenset(labels)))
            labels = set()
    if stack:
        raise ListingError(f"{path.name}: .repeat without .endr")
    return out


def count(name: str, directory: Path = LISTINGS) -> Count:
    """Count the listing ``name`` (``NAME.asm`` in ``directory``, by default the model
    firmware's listings)."""
    total = Count(name)
    for line in expand(name, Path(directory)):
        try:
            total.add(step(line.text))
        except ValueError as exc:
            raise ListingError(f"{line.file}:{line.no}: {line.text}: {exc}") from None
    return total
