"""Run an instruction listing's one path on its data: a check that the path a listing charges
(:mod:`~firmware_model.isa.listing`) is the path its operands take, and of what it computes.

The counter believes a listing's ``{taken}``/``{not taken}`` annotations. :func:`execute`
runs the same lines (includes expanded, repeats unrolled, as the counter reads them) and
raises :class:`ExecutionError`, naming ``file:line`` and the instruction, when a branch's
annotation disagrees with the flags its data leaves (or ``{bits N}`` with R0); when a branch
is taken but the path goes on at a line that is not its label (that line would not run);
when the model has no semantics for an instruction; when it reads a word nothing wrote or a
word at an odd address (the cycle table assumes even ones); when RET does not pop what its
CALL pushed.

The model: RW0-RW7 (16-bit words; R0-R7 are RW4-RW7's bytes, low byte first; RLi is
RW(2i+1):RW(2i)), A (32 bits, AH:AL), the CCR's N Z V C, SP, and a memory of 16-bit words at
even byte addresses (the stack, LINK frames, @RWi+disp8, @RWj, @RWj+, and the ROM tables
@RWj+disp16 names). Addresses are 16-bit byte addresses in one bank; values unsigned
integers. Each instruction does what MAME's F2MC-16 core (f2mc16.cpp, the cycle table's
source) does: MOV A,x and MOVW A,x move AL to AH first; SWAP exchanges AL's bytes, SWAPW AH
and AL; MULUW and DIVUW leave N and Z. One exception: ADDL sets C from the carry out of bit
31, as the CPU does (MAME's doADD_32 sums in 32 bits and never sets it; f_div's BNC needs it).
Only the forms the float library's listings use are modelled. The result is the
:class:`State` the path leaves, with the lines it ran: instructions, not cycles (those are
:func:`~firmware_model.isa.listing.count`'s).
"""
from __future__ import annotations

import re
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from . import cycles
from .listing import LISTINGS, expand, split_line, step

MASK16 = 0xFFFF
STACK_TOP = 0x1000
"""SP at the start of a path: an even internal-RAM address (the listings only use the stack
relative to SP)."""
ROM_TABLES: dict[str, tuple[int, tuple[int, ...]]] = {
    "pow2": (0xF000, tuple(1 << i for i in range(16))),   # f_round: 16 words, 2^0-2^15
}
"""The constant tables a listing names as a disp16 (``@RWj+disp16:NAME``): address, words."""


class ExecutionError(ValueError):
    """A listing whose path its data does not take, or that the model cannot run: names the
    file, the line and the instruction."""


class _Fault(Exception):
    """What went wrong inside one instruction; :func:`execute` adds where."""


@dataclass
class State:
    """The registers, flags and word memory a path leaves, and the lines it ran
    (``visited``: file name and line number, one entry an instruction executed)."""

    rw: list[int] = field(default_factory=lambda: [0] * 8)
    a: int = 0
    n: bool = False
    z: bool = False
    v: bool = False
    c: bool = False
    sp: int = STACK_TOP
    memory: dict[int, int] = field(default_factory=dict)
    visited: list[tuple[str, int]] = field(default_factory=list)
    calls: list[int] = field(default_factory=list)   # return addresses CALL pushed

    @property
    def ah(self) -> int:
        return self.a >> 16

    @property
    def al(self) -> int:
        return self.a & MASK16

    def set_al(self, value: int) -> None:
        self.a = (self.a & 0xFFFF0000) | (value & MASK16)

    def load_a(self, value: int) -> None:
        """A MOV/MOVW/POPW into A: AL moves to AH, ``value`` into AL."""
        self.a = (self.al << 16) | (value & MASK16)

    def r(self, i: int) -> int:
        word = self.rw[4 + i // 2]
        return word >> 8 if i & 1 else word & 0xFF

    def set_nz(self, value: int, bits: int) -> None:
        self.z = (value & ((1 << bits) - 1)) == 0
        self.n = bool(value >> (bits - 1) & 1)

    def add(self, lhs: int, rhs: int, bits: int, carry: int = 0) -> int:
        """lhs + rhs (+ carry), flags N Z V C set (MAME's doADD/doADDC)."""
        total = lhs + rhs + carry
        result = total & ((1 << bits) - 1)
        self.c = total >> bits != 0
        self.v = bool(((result ^ lhs) & (result ^ rhs)) >> (bits - 1) & 1)
        self.set_nz(result, bits)
        return result

    def sub(self, lhs: int, rhs: int, bits: int, borrow: int = 0) -> int:
        """lhs - rhs (- borrow), flags N Z V C set, C the borrow (MAME's doSUB/doCMP/doSUBC)."""
        result = (lhs - rhs - borrow) & ((1 << bits) - 1)
        self.c = lhs < rhs + borrow
        self.v = bool(((lhs ^ rhs) & (lhs ^ result)) >> (bits - 1) & 1)
        self.set_nz(result, bits)
        return result

    def read_word(self, address: int) -> int:
        if address & 1 or address not in self.memory:
            raise _Fault(f"reads a word at 0x{address:04X}, " + (
                "an odd address" if address & 1 else "which nothing wrote"))
        return self.memory[address]

    def write_word(self, address: int, value: int) -> None:
        if address & 1:
            raise _Fault(f"writes a word at 0x{address:04X}, an odd address")
        self.memory[address] = value & MASK16

    def push(self, value: int) -> None:
        self.sp = (self.sp - 2) & MASK16
        self.write_word(self.sp, value)

    def pop(self) -> int:
        value = self.read_word(self.sp)
        self.sp = (self.sp + 2) & MASK16
        return value


# the float library's data: IEEE single floats, high word first
def float_bits(x: float) -> int:
    """x rounded to float32, as its 32-bit pattern."""
    return int(struct.unpack(">I", struct.pack(">f", x))[0])


def float_args(x: float, y: float | None = None) -> dict[str, int]:
    """A soft-float routine's arguments as registers: x in RW1:RW0, y in RW5:RW4."""
    regs = {"RL0": float_bits(x)}
    if y is not None:
        regs["RL2"] = float_bits(y)
    return regs


def result_bits(state: State) -> int:
    """A soft-float routine's result, A (AH the high word, AL the low word), as a pattern."""
    return state.a


# operands
_R = re.compile(r"R([0-7])$")
_RW = re.compile(r"RW([0-7])$")
_RL = re.compile(r"RL([0-3])$")
_DISP8 = re.compile(r"@RW([0-7])\+(0x[0-9A-Fa-f]+|\d+)$")
_DISP16 = re.compile(r"@RW([0-3])\+disp16:(\w+)$")
_INDIRECT = re.compile(r"@RW([0-3])(\+?)$")


def _immediate(op: str, bits: int) -> int:
    value = int(op[1:], 0)
    if not -(1 << (bits - 1)) <= value < 1 << bits:
        raise _Fault(f"{op} does not fit {bits} bits")
    return value & ((1 << bits) - 1)


def _address(s: State, op: str, size: int) -> int:
    """The byte address an ``@`` operand names; @RWj+ steps RWj on by ``size`` bytes."""
    if m := _DISP8.match(op):
        disp = int(m[2], 0)
        if disp > 0xFF:
            raise _Fault(f"{op}: the displacement is 8 bits")
        return (s.rw[int(m[1])] + disp - (disp & 0x80) * 2) & MASK16
    if m := _DISP16.match(op):
        if m[2] not in ROM_TABLES:
            raise _Fault(f"{op}: no table {m[2]} (execute.ROM_TABLES)")
        return (s.rw[int(m[1])] + ROM_TABLES[m[2]][0]) & MASK16
    if m := _INDIRECT.match(op):
        i = int(m[1])
        address = s.rw[i]
        if m[2]:
            s.rw[i] = (address + size) & MASK16
        return address
    raise _Fault(f"no model of the operand {op}")


def _read(s: State, op: str, bits: int) -> int:
    """A byte (Ri, #imm8), word (RWi, #imm16, @...) or long (RLi, #imm32, @...) operand's
    value; a long in memory is two words, the low one first."""
    if op.startswith("#"):
        return _immediate(op, bits)
    if bits == 8 and (m := _R.match(op)):
        return s.r(int(m[1]))
    if bits == 16 and (m := _RW.match(op)):
        return s.rw[int(m[1])]
    if bits == 32 and (m := _RL.match(op)):
        return s.rw[2 * int(m[1]) + 1] << 16 | s.rw[2 * int(m[1])]
    if bits == 8:
        raise _Fault(f"no model of the byte operand {op}")
    address = _address(s, op, bits // 8)
    return sum(s.read_word((address + k) & MASK16) << 8 * k for k in range(0, bits // 8, 2))


def _write(s: State, op: str, bits: int, value: int) -> None:
    """Store a word (RWi, @...) or long (RLi, @...) operand."""
    if bits == 16 and (m := _RW.match(op)):
        s.rw[int(m[1])] = value & MASK16
    elif bits == 32 and (m := _RL.match(op)):
        s.rw[2 * int(m[1]):2 * int(m[1]) + 2] = [value & MASK16, value >> 16 & MASK16]
    else:
        address = _address(s, op, bits // 8)
        for k in range(0, bits // 8, 2):
            s.write_word((address + k) & MASK16, value >> 8 * k)


# the instructions, by family: each takes the state, the mnemonic and the operands; a branch
# returns whether it is taken
Handler = Callable[[State, str, list[str]], bool | None]
_LOGIC: dict[str, Callable[[int, int], int]] = {
    "AND": lambda x, y: x & y, "OR": lambda x, y: x | y, "XOR": lambda x, y: x ^ y}
_CONDITIONS: dict[str, Callable[[State], bool]] = {
    "BEQ": lambda s: s.z, "BZ": lambda s: s.z, "BNE": lambda s: not s.z, "BNZ": lambda s: not s.z,
    "BC": lambda s: s.c, "BLO": lambda s: s.c, "BNC": lambda s: not s.c, "BHS": lambda s: not s.c,
    "BN": lambda s: s.n, "BP": lambda s: not s.n, "BLT": lambda s: s.n != s.v,
    "BGE": lambda s: s.n == s.v, "BLE": lambda s: s.n != s.v or s.z,
    "BGT": lambda s: not (s.n != s.v or s.z), "BLS": lambda s: s.c or s.z,
    "BHI": lambda s: not (s.c or s.z), "BRA": lambda s: True}


def _move(s: State, mn: str, ops: list[str]) -> None:
    """MOV A,Ri (a byte), MOVW, MOVL: into A, AL moves to AH first (MOVL: all of A); N Z
    from what moved."""
    dst, src = ops
    if mn == "MOVL":
        if dst == "A":
            s.a = _read(s, src, 32)
        else:
            _write(s, dst, 32, s.a)
        s.set_nz(s.a, 32)
    elif dst == "A":
        s.load_a(_read(s, src, 8 if mn == "MOV" else 16))
        s.set_nz(s.al, 8 if mn == "MOV" else 16)
    else:
        value = s.al if src == "A" else _read(s, src, 16)
        _write(s, dst, 16, value)
        s.set_nz(value, 16)


def _combine(s: State, mn: str, lhs: int, rhs: int, bits: int) -> int | None:
    """``mn`` (ADD, SUB, CMP, ADDC, SUBC, AND, OR, XOR, with its W or L) on two operands of
    ``bits`` bits, flags set: the result (None for a compare). AND/OR/XOR clear V, leave C."""
    op = mn.rstrip("WL")
    if op in _LOGIC:
        result = _LOGIC[op](lhs, rhs)
        s.set_nz(result, bits)
        s.v = False
        return result
    carry = int(s.c) if op in ("ADDC", "SUBC") else 0
    if op.startswith("ADD"):
        return s.add(lhs, rhs, bits, carry)
    result = s.sub(lhs, rhs, bits, carry)
    return None if op == "CMP" else result


def _arithmetic(s: State, mn: str, ops: list[str]) -> None:
    """Arithmetic and logic: ``op A`` (AH op AL, into AL), ``op A,src`` (AL op src, into AL;
    ADDL/SUBL/CMPL: all of A), ``op RWi,A`` (RWi op AL, into RWi), NEGW A, DECW RWi (N Z V),
    OR A,#imm8 (into AL's low byte; N Z from it)."""
    if mn == "NEGW":
        s.set_al(s.sub(0, s.al, 16))
    elif mn == "DECW":
        value = (_read(s, ops[0], 16) - 1) & MASK16
        _write(s, ops[0], 16, value)
        s.set_nz(value, 16)
        s.v = value == 0x7FFF
    elif mn == "OR":
        s.a |= _read(s, ops[1], 8)
        s.set_nz(s.al, 8)
        s.v = False
    elif mn.endswith("L"):
        result = _combine(s, mn, s.a, _read(s, ops[1], 32), 32)
        s.a = s.a if result is None else result
    elif ops[0] != "A":
        result = _combine(s, mn, _read(s, ops[0], 16), s.al, 16)
        assert result is not None
        _write(s, ops[0], 16, result)
    else:
        lhs, rhs = (s.ah, s.al) if len(ops) == 1 else (s.al, _read(s, ops[1], 16))
        result = _combine(s, mn, lhs, rhs, 16)
        if result is not None:
            s.set_al(result)


def _shift(s: State, mn: str, ops: list[str]) -> None:
    """LSLW/LSRW A (AL by a bit) and LSRL A,R0 (A by R0 bits; R0 = 0: C clear, Z set): C the
    last bit out, N Z from the result. SWAP (AL's bytes), SWAPW (AH and AL): no flags;
    ZEXTW (AH = 0): N Z."""
    if mn == "LSRL":
        if ops[1] != "R0":
            raise _Fault("LSRL shifts by R0 only")
        count = s.r(0)
        if count == 0:
            s.c, s.z = False, True
            return
        s.c = bool(s.a >> (count - 1) & 1)
        s.a >>= count
        s.set_nz(s.a, 32)
    elif mn in ("LSLW", "LSRW"):
        s.c = bool(s.al >> 15) if mn == "LSLW" else bool(s.al & 1)
        s.set_al(s.al << 1 if mn == "LSLW" else s.al >> 1)
        s.set_nz(s.al, 16)
    elif mn == "SWAP":
        s.set_al((s.al & 0xFF) << 8 | s.al >> 8)
    elif mn == "SWAPW":
        s.a = s.al << 16 | s.ah
    else:
        s.a = s.al
        s.set_nz(s.a, 32)


def _multiply_divide(s: State, mn: str, ops: list[str]) -> None:
    """MULUW A (AH x AL), MULUW A,RWi (RWi x AL): the 32-bit product in A, no flags. DIVUW
    A,RWi: A / RWi, the quotient in AL, the remainder in RWi; on an overflow V set and A,
    RWi as they were; a divide by zero sets V and C."""
    if mn == "MULUW":
        s.a = (s.ah if len(ops) == 1 else _read(s, ops[1], 16)) * s.al
        return
    divisor = _read(s, ops[1], 16)
    s.v = s.c = divisor == 0
    if divisor:
        quotient, remainder = divmod(s.a, divisor)
        if quotient > MASK16:
            s.v = True
        else:
            s.set_al(quotient)
            _write(s, ops[1], 16, remainder)


def _branch(s: State, mn: str, ops: list[str]) -> bool:
    """Bcc and BRA on the flags; CBNE A,#imm8 / CWBNE A,#imm16 compare first (flags set),
    taken if not equal."""
    if mn == "CBNE":
        s.sub(s.al & 0xFF, _immediate(ops[1], 8), 8)
    elif mn == "CWBNE":
        s.sub(s.al, _immediate(ops[1], 16), 16)
    return not s.z if mn in ("CBNE", "CWBNE") else _CONDITIONS[mn](s)


def _stack(s: State, mn: str, ops: list[str]) -> None:
    """CALL (pushes a return address: here the next step's index), RET (must pop it),
    LINK #imm8 (RW3 pushed, RW3 = SP, SP - imm8), UNLINK, PUSHW A (AL) and POPW A (AL moves
    to AH first; no flags)."""
    if mn == "CALL":
        s.calls.append((len(s.visited) + 1) & MASK16)
        s.push(s.calls[-1])
    elif mn == "RET":
        if not s.calls:
            raise _Fault("RET with no CALL on the path")
        expected, popped = s.calls.pop(), s.pop()
        if popped != expected:
            raise _Fault(f"RET pops 0x{popped:04X}, not the return address its CALL pushed "
                         f"(0x{expected:04X}): the stack is unbalanced")
    elif mn == "LINK":
        s.push(s.rw[3])
        s.rw[3] = s.sp
        s.sp = (s.sp - _immediate(ops[0], 8)) & MASK16
    elif mn == "UNLINK":
        s.sp = s.rw[3]
        s.rw[3] = s.pop()
    elif mn == "PUSHW":
        s.push(s.al)
    else:
        s.load_a(s.pop())


_WORD_SOURCES = ("RWi", "#imm", "@RWi+disp8", "@RWj", "@RWj+", "@RWj+disp16")
HANDLERS: dict[str, Handler] = {
    "MOV A,Ri": _move,
    **{f"MOVW A,{k}": _move for k in _WORD_SOURCES},
    **{f"MOVW {k}": _move for k in ("RWi,A", "RWi,RWi", "RWi,#imm", "@RWi+disp8,A",
                                     "@RWj,A", "@RWj+,A")},
    **{f"MOVL {k}": _move for k in ("A,RLi", "RLi,A", "A,@RWi+disp8", "@RWi+disp8,A")},
    **{f"{m} A": _arithmetic for m in ("ADDW", "SUBW", "CMPW", "ANDW", "ORW", "XORW", "NEGW")},
    **{f"{m} A,RWi": _arithmetic for m in ("ADDW", "SUBW", "CMPW", "ANDW", "ORW", "XORW",
                                            "ADDCW", "SUBCW")},
    **{f"{m} A,#imm": _arithmetic for m in ("ADDW", "SUBW", "CMPW", "ANDW", "ORW", "XORW", "OR")},
    "ADDW A,@RWi+disp8": _arithmetic, "CMPW A,@RWi+disp8": _arithmetic,
    "ADDW RWi,A": _arithmetic, "SUBW RWi,A": _arithmetic, "DECW RWi": _arithmetic,
    **{f"{m} A,{k}": _arithmetic for m in ("ADDL", "SUBL", "CMPL") for k in ("RLi", "#imm")},
    **{k: _shift for k in ("LSLW A", "LSRW A", "LSRL A,Ri", "SWAP", "SWAPW", "ZEXTW")},
    "MULUW A": _multiply_divide, "MULUW A,RWi": _multiply_divide,
    "DIVUW A,RWi": _multiply_divide,
    **{f"{b} rel": _branch for b in _CONDITIONS},
    "CBNE A,#imm,rel": _branch, "CWBNE A,#imm,rel": _branch,
    **{k: _stack for k in ("CALL addr16", "RET", "LINK #imm", "UNLINK", "PUSHW A", "POPW A")},
}
"""The instruction table's forms (:data:`cycles.FORMS` keys) the model runs."""


def execute(name: str, regs: Mapping[str, int], directory: Path = LISTINGS) -> State:
    """Run the listing ``name`` (``NAME.asm`` in ``directory``) from the registers ``regs``
    (``RW0``-``RW7``, ``RL0``-``RL3``; the rest and A 0; SP at :data:`STACK_TOP`), checking
    every branch's annotation and that a taken branch lands where the path goes on."""
    directory = Path(directory)
    path = expand(name, directory)
    s = State()
    s.memory.update({address + 2 * k: word for address, words in ROM_TABLES.values()
                     for k, word in enumerate(words)})
    for reg, value in regs.items():
        if not (_RW.match(reg) or _RL.match(reg)):
            raise ValueError(f"no register {reg!r} to set (RW0-RW7, RL0-RL3)")
        _write(s, reg, 32 if reg.startswith("RL") else 16, value)
    for i, (fname, no, text, _) in enumerate(path):
        where = f"{fname}:{no}: {text}"
        mnemonic, ops, notes = split_line(text)
        try:
            counted = step(text)
        except ValueError as exc:
            raise ExecutionError(f"{where}: {exc}") from None
        form = counted.form
        run = HANDLERS.get(form)
        if run is None:
            raise ExecutionError(f"{where}: the executor has no model of {form!r}")
        if counted.bits is not None and s.r(0) != counted.bits:
            raise ExecutionError(f"{where}: R0 is {s.r(0)}, the listing charges "
                                 f"{{bits {counted.bits}}}")
        try:
            taken = run(s, mnemonic, ops)
        except _Fault as exc:
            raise ExecutionError(f"{where}: {exc}") from None
        s.visited.append((fname, no))
        if taken is None:
            continue
        if cycles.FORMS[form].taken is not None and taken != ("taken" in notes):
            said = "taken" if "taken" in notes else "not taken"
            raise ExecutionError(
                f"{where}: the listing says {said}, the data says "
                f"{'taken' if taken else 'not taken'} (N={s.n:d} Z={s.z:d} V={s.v:d} "
                f"C={s.c:d}, AL=0x{s.al:04X})")
        if taken and i + 1 < len(path):
            target, (nfile, nno, ntext, labels) = ops[-1], path[i + 1]
            if target not in labels:
                raise ExecutionError(
                    f"{where}: taken to {target}, but the path goes on at {nfile}:{nno} "
                    f"({ntext}), which is not at {target}: it would not run")
    return s
