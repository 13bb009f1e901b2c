"""The F2MC-16LX instruction cycles the model firmware's listings use (machine cycles, one
62.5 ns tick each at 16 MHz), each form with its source.

Fujitsu's own table (F2MC-16LX programming manual, Appendix B.8, the "~" column) is not at
hand here, apart from the rows cycle_costs.py quotes from the MB90560 hardware manual. So the
figures are those of an independent model of the ISA, MAME's F2MC-16 core
(``src/devices/cpu/f2mc16/f2mc16.cpp``, read at commit 7b5b5d59, its ``case`` comment named
in each row), a secondary source:

* it charges one figure per opcode and addressing mode, the mode's cost folded in, and says
  "TODO: Correction values applied to instruction cycles": no access corrections. The
  MB90420G/5G data sheet's Table 5 gives those: +0 for a byte, word or long operand in an
  internal register or in internal memory at an even address, which is where the model
  firmware keeps its data (I/O registers, internal RAM, words aligned), so none is added;
* where Fujitsu's figure is at hand the two are compared (``MANUAL``): MULUW A and DIVUW
  agree; RETI does not (MAME 17, the manual 11 + 6 x Z) and the manual's figure is used;
  MAME charges the interrupt entry nothing, the manual 24 (cycle_costs.py ``entry``);
* MAME is inconsistent in places, and the listings keep away from those forms: the short
  MOVW A,@RWi+disp8 (B8-BF) is charged 10 where the same operation's ea form (73 90-97) is
  5 (the ea form is the one in this table); CBNE Ri,#imm8 is 13/12 against CWBNE's 8/7;
  PUSHW of eight registers (29 + 3 x 8 = 53) is longer than the manual's longest
  instruction (POPW RW0-RW7, 45), so its register lists are not the manual's either.

The worst case adds, to every instruction, the data sheet's Table 6 program-fetch
correction (+2, internal memory, an instruction across a word boundary: "these correction
values should be used for 'worst case' calculations"), and to every access to a CAN
message buffer the wait while the controller uses it (up to 64 machine cycles, the MB90390
series hardware manual, the same CAN block).
"""
from __future__ import annotations

from dataclasses import dataclass

MAME = "MAME f2mc16.cpp"


@dataclass(frozen=True)
class Form:
    """One instruction form: ``cycles`` (machine cycles; a conditional branch's when not
    taken), ``taken`` (a conditional branch's when taken, else None), ``per_register``
    (added for each register of a PUSHW/POPW list), ``per_bit`` (added for each bit of a
    shift by a count, which the listing gives as ``{bits N}``), and the source."""

    cycles: int
    source: str
    taken: int | None = None
    per_register: int = 0
    per_bit: int = 0


def _m(cycles: int, case: str, taken: int | None = None, per_register: int = 0,
       per_bit: int = 0) -> Form:
    return Form(cycles, f"{MAME}, case {case}", taken, per_register, per_bit)


FETCH_WORST = 2
"""MB90420G/5G data sheet, Table 6: program fetch, internal memory, word boundary: +2."""
CAN_BUFFER_WAIT_MAX = 64
"""The CPU's wait on a CAN message buffer access while the controller uses it, at most
(MB90390 series hardware manual, CAN controller)."""

_BRANCHES = ("BEQ", "BZ", "BNE", "BNZ", "BC", "BLO", "BNC", "BHS", "BN", "BP", "BLT", "BGE",
             "BLE", "BGT", "BLS", "BHI")

FORMS: dict[str, Form] = {
    # byte transfers
    "NOP": _m(1, "0x00 // NOP"),
    "MOV A,#imm": _m(2, "0x42 // MOV A, #imm8"),
    "MOV A,dir": _m(3, "0x40 // MOV A, dir"),
    "MOV dir,A": _m(3, "0x41 // MOV dir, A"),
    "MOV A,io": _m(3, "0x50 // MOV A, io"),
    "MOV io,A": _m(3, "0x51 // MOV io, A"),
    "MOV A,addr16": _m(4, "0x52 // MOV A, addr16"),
    "MOV addr16,A": _m(4, "0x53 // MOV addr16, A"),
    "MOV io,#imm": _m(5, "0x54 // MOV io, #imm8"),
    "MOV dir,#imm": _m(5, "0x44 // MOV dir, #imm8"),
    "MOVN A,#imm": _m(1, "0xD0-0xDF // MOVN A, #imm4"),
    "MOV A,Ri": _m(2, "0x80-0x87 // MOV A, Rx"),
    "MOV Ri,A": _m(2, "0x90-0x97 // MOV Rx, A"),
    "MOV Ri,#imm": _m(2, "0xA0-0xA7 // MOV Rx, #imm8"),
    "MOV A,@RWi+disp8": _m(5, "0x72 0x90-0x97 // MOV A, @RWx + disp8"),
    "MOV @RWi+disp8,A": _m(5, "0x72 0xB0-0xB7 // MOV @RWx + disp8, A"),
    "MOV A,@RWj+": _m(7, "0x72 0x8C-0x8F // MOV A, @RWx+"),
    "MOV @RWj+,A": _m(7, "0x72 0xAC-0xAF // MOV @RWx+, A"),
    "MOVX A,#imm": _m(2, "0x43 // MOVX A, #imm8"),
    "MOVX A,Ri": _m(2, "0xB0-0xB7 // MOVX A, Rx"),
    # word and long transfers
    "MOVW A,#imm": _m(2, "0x4A // MOVW A, #imm16"),
    "MOVL A,#imm": _m(3, "0x4B // MOVL A, #imm32"),
    "MOVL A,RLi": _m(4, "0x71 0x80-0x87 // MOVL A, RLx"),
    "MOVL RLi,A": _m(4, "0x71 0xA0-0xA7 // MOVL RLx, A"),
    "MOVL A,@RWi+disp8": _m(7, "0x71 0x90-0x97 // MOVL A, @RWx + disp8"),
    "MOVL @RWi+disp8,A": _m(7, "0x71 0xB0-0xB7 // MOVL @RWx + disp8, A"),
    "MOVW RWi,RWi": _m(4, "0x7B 0x00-0xE7 (bits 4-3 clear) // MOVW RWx, RWy"),
    "MOVW A,dir": _m(3, "0x48 // MOVW A, dir"),
    "MOVW dir,A": _m(3, "0x49 // MOVW dir, A"),
    "MOVW A,io": _m(3, "0x58 // MOVW A, io"),
    "MOVW io,A": _m(3, "0x59 // MOVW io, A"),
    "MOVW io,#imm": _m(5, "0x56 // MOVW io, #imm16"),
    "MOVW A,addr16": _m(4, "0x5A // MOVW A, addr16"),
    "MOVW addr16,A": _m(4, "0x5B // MOVW addr16, A"),
    "MOVW A,RWi": _m(2, "0x88-0x8F // MOVW A, RWx"),
    "MOVW RWi,A": _m(2, "0x98-0x9F // MOVW RWx, A"),
    "MOVW RWi,#imm": _m(2, "0xA8-0xAF // MOVW RWx, #imm16"),
    "MOVW A,@RWi+disp8": _m(5, "0x73 0x90-0x97 // MOVW A, @RWx + disp8"),
    "MOVW @RWi+disp8,A": _m(5, "0x73 0xB0-0xB7 // MOVW @RWx + disp8, A"),
    "MOVW A,@RWj": _m(5, "0x73 0x88-0x8B // MOVW A, @RWx"),
    "MOVW @RWj,A": _m(5, "0x73 0xA8-0xAB // MOVW @RWx, A"),
    "MOVW A,@RWj+": _m(7, "0x73 0x8C-0x8F // MOVW A, @RWx+"),
    "MOVW @RWj+,A": _m(7, "0x73 0xAC-0xAF // MOVW @RWx+, A"),
    "MOVW A,@RWj+disp16": _m(5, "0x73 0x98-0x9B // MOVW A, @RWx + disp16"),
    "MOVW A,SP": _m(1, "0x46 // MOVW A, SP"),
    # arithmetic and logic
    "ADD A,#imm": _m(2, "0x30 // ADD A, #imm8"),
    "SUB A,#imm": _m(2, "0x31 // SUB A, #imm8"),
    "CMP A,#imm": _m(2, "0x33 // CMP A, #imm8"),
    "AND A,#imm": _m(2, "0x34 // AND A, #imm8"),
    "OR A,#imm": _m(2, "0x35 // OR A, #imm8"),
    "XOR A,#imm": _m(2, "0x36 // XOR A, #imm8"),
    "ADDW A": _m(2, "0x28 // ADDW A"),
    "SUBW A": _m(2, "0x29 // SUBW A"),
    "CMP A": _m(1, "0x23 // CMP A"),
    "CMPW A": _m(1, "0x2B // CMPW A"),
    "XORW A": _m(2, "0x2E // XORW A"),
    "ANDW A": _m(2, "0x2C // ANDW A"),
    "ORW A": _m(2, "0x2D // ORW A"),
    "NEG A": _m(2, "0x03 // NEG A"),
    "NEGW A": _m(2, "0x0B // NEGW A"),
    "NOTW A": _m(2, "0x3F // NOTW A"),
    "ADDW A,#imm": _m(2, "0x38 // ADDW A, #imm16"),
    "CMPW A,#imm": _m(2, "0x3B // CMPW A, #imm16"),
    "ANDW A,#imm": _m(2, "0x3C // ANDW A, #imm16"),
    "ORW A,#imm": _m(2, "0x3D // ORW A, #imm16"),
    "XORW A,#imm": _m(2, "0x3E // XORW A, #imm16"),
    "SUBW A,#imm": _m(2, "0x39 // SUBW A, #imm16"),
    "SUBW A,RWi": _m(3, "0x76 0x20-0x27 // SUBW A, RWx"),
    "SUBW RWi,A": _m(3, "0x77 0x20-0x27 // SUBW RWx, A"),
    "ADDCW A,RWi": _m(3, "0x76 0x40-0x47 // ADDCW A, RWx"),
    "SUBCW A,RWi": _m(3, "0x77 0x40-0x47 // SUBCW A, RWx"),
    "ANDW A,RWi": _m(3, "0x76 0x80-0x87 // ANDW A, RWx"),
    "ORW A,RWi": _m(3, "0x76 0xA0-0xA7 // ORW A, RWx"),
    "XORW A,RWi": _m(3, "0x76 0xC0-0xC7 // XORW A, RWx"),
    "ADDL A,#imm": _m(4, "0x18 // ADDL A, #imm32"),
    "SUBL A,#imm": _m(4, "0x19 // SUBL A, #imm32"),
    "CMPL A,#imm": _m(3, "0x1B // CMPL A, #imm32"),
    "ADDL A,RLi": _m(6, "0x70 0x00-0x07 // ADDL A, RLx"),
    "SUBL A,RLi": _m(6, "0x70 0x20-0x27 // SUBL A, RLx"),
    "CMPL A,RLi": _m(6, "0x70 0x60-0x67 // CMPL A, RLx"),
    "ADDW A,RWi": _m(3, "0x76 0x00-0x07 // ADDW A, RWx"),
    "ADDW A,@RWi+disp8": _m(6, "0x76 0x10-0x17 // ADDW A, @RWx + disp8"),
    "ADDW RWi,A": _m(3, "0x77 0x00-0x07 // ADDW RWx, A"),
    "CMPW A,RWi": _m(2, "0x76 0x60-0x67 // CMPW A, RWx"),
    "CMPW A,@RWi+disp8": _m(5, "0x76 0x70-0x77 // CMPW A, @RWx + disp8"),
    "INC Ri": _m(3, "0x72 0x40-0x47 // INC Rx"),
    "INC @RWi+disp8": _m(7, "0x72 0x50-0x57 // INC @RWx + disp8"),
    "INCW RWi": _m(3, "0x73 0x40-0x47 // INCW RWx"),
    "INCW @RWi+disp8": _m(5, "0x73 0x50-0x57 // INCW @RWx + disp8"),
    "DECW RWi": _m(3, "0x73 0x60-0x67 // DECW RWx"),
    "LSLW A": _m(2, "0x0C // LSLW A"),
    "LSRW A": _m(2, "0x0F // LSRW A"),
    "ASRW A": _m(2, "0x0E // ASRW A"),
    "LSRL A,Ri": _m(6, "0x6F 0x1F // LSRL A, R0: 6 + 1 a bit shifted", per_bit=1),
    "ROLC A": _m(2, "0x6F 0x07 // ROLC A (AL's low byte)"),
    "SWAP": _m(3, "0x16 // SWAP"),
    "SWAPW": _m(2, "0x1E // SWAPW"),
    "EXT": _m(1, "0x14 // EXT"),
    "ZEXT": _m(1, "0x15 // ZEXT"),
    "EXTW": _m(2, "0x1C // EXTW"),
    "ZEXTW": _m(1, "0x1D // ZEXTW"),
    "MULUW A": _m(11, "0x2F // MULUW A (AH non-zero; 3 when AH = 0)"),
    "MULUW A,RWi": _m(12, "0x78 0x20-0x27 // MULUW A, RWx (non-zero)"),
    "DIVUW A,RWi": _m(22, "0x78 0xA0-0xA7 // DIVUW A, RWx (normal)"),
    # branches: not taken, taken
    "BRA rel": _m(4, "0x60 // BRA (take_branch)"),
    **{f"{b} rel": _m(3, f"0xF0-0xFF // {b}", taken=4) for b in _BRANCHES},
    "CBNE A,#imm,rel": _m(4, "0x2A // CBNE A, #imm8", taken=4),
    "CWBNE A,#imm,rel": _m(4, "0x3A // CWBNE A, #imm16, disp8", taken=5),
    "CWBNE RWi,#imm,rel": _m(7, "0x70 0x40-0x47 // CWBNE RWx, #imm16, disp8", taken=8),
    "DBNZ Ri,rel": _m(6, "0x74 0xE0-0xE7 // DBNZ Rx, disp8", taken=7),
    "DWBNZ RWi,rel": _m(6, "0x76 0xE0-0xE7 // DWBNZ RWx, disp8", taken=7),
    "BBC io:bp,rel": _m(6, "0x6C 0x80-0x87 // BBC io:bp, disp8", taken=7),
    "BBS io:bp,rel": _m(6, "0x6C 0xA0-0xA7 // BBS io:bp, disp8", taken=7),
    "BBC dir:bp,rel": _m(7, "0x6C 0x88-0x8F // BBC dir:bp, disp8", taken=8),
    "BBS dir:bp,rel": _m(7, "0x6C 0xA8-0xAF // BBS dir:bp, disp8", taken=8),
    "JMP @A": _m(2, "0x61 // JMP @A"),
    "JMP addr16": _m(3, "0x62 // JMP addr16"),
    # bits
    "SETB io:bp": _m(7, "0x6C 0x60-0x67 // SETB io:bp"),
    "CLRB io:bp": _m(7, "0x6C 0x40-0x47 // CLRB io:bp"),
    "SETB dir:bp": _m(7, "0x6C 0x68-0x6F // SETB dir:bp"),
    "CLRB dir:bp": _m(7, "0x6C 0x48-0x4F // CLRB dir:bp"),
    "SETB addr16:bp": _m(7, "0x6C 0x78-0x7F // SETB addr16:bp"),
    "CLRB addr16:bp": _m(7, "0x6C 0x58-0x5F // CLRB addr16:bp"),
    # calls, stack, processor state
    "CALL addr16": _m(6, "0x64 // CALL addr16"),
    "RET": _m(4, "0x67 // RET"),
    "RETI": Form(11, "manual: RETI 11 + 6 x Z, Z = 0 (MB90420/5 §6.4.5; MB90560 §6.7, "
                 "Table 6.7-3); MAME 0x6B // RETI charges 17"),
    "PUSHW A": _m(4, "0x4C // PUSHW A"),
    "POPW A": _m(3, "0x5C // POPW A"),
    "PUSHW rlst": _m(29, "0x4F // PUSHW (register bitmap): 29 + 3 a register", per_register=3),
    "POPW rlst": _m(0, "0x5F // POPW register list: 3 a register", per_register=3),
    "LINK #imm": _m(6, "0x08 // LINK #imm8"),
    "UNLINK": _m(5, "0x09 // UNLINK"),
    "MOV ILM,#imm": _m(2, "0x1A // MOV ILM, #imm8"),
    "MOV RP,#imm": _m(2, "0x0A // MOV RP, #imm8"),
    "AND CCR,#imm": _m(3, "0x24 // AND CCR, #imm8"),
    "OR CCR,#imm": _m(3, "0x25 // OR CCR, #imm8"),
    "ADDSP #imm": _m(3, "0x17 // ADDSP #imm8"),
}

MANUAL = {"MULUW A": 11, "DIVUW A,RWi": 22, "RETI": 11}
"""Fujitsu's figures where they are at hand (MB90560 hardware manual, Appendix B, Table
B.8-6; "Interrupts", Table 6.7-3): the table must agree (``tests/firmware_model/isa``)."""
