"""The listing executor: the float library's charged paths, run on their charged operands,
give the correctly rounded float32 and run exactly the instructions the counter counts; a
listing whose annotations its data contradicts, a taken branch past the line the path goes
on at, and the model's other refusals raise, naming the line."""
from __future__ import annotations

import math
import shutil
import struct

import pytest

from firmware_model.isa import cycles
from firmware_model.isa.execute import (
    HANDLERS, STACK_TOP, ExecutionError, execute, float_args, float_bits, result_bits)
from firmware_model.isa.listing import LISTINGS, count


def f32(x: float) -> float:
    """x rounded to float32 (to nearest, ties to even)."""
    return float(struct.unpack(">f", struct.pack(">f", x))[0])


def round_half_away(x: float) -> float:
    """C roundf."""
    return math.copysign(math.floor(abs(x) + 0.5), x)


SUM_OF_SQUARES = f32(f32(f32(1.234) ** 2) + f32(f32(5.678) ** 2))
"""1.234^2 + 5.678^2 as float32 arithmetic has it: the argument hypotf(1.234, 5.678) gives
sqrtf, f_sqrt's charged operand."""
CHARGED = {
    "f_add": ((1.234, 5.678), lambda x, y: x + y),
    "f_mul": ((1.234, 5.678), lambda x, y: x * y),
    "f_div": ((1.234, 5.678), lambda x, y: x / y),
    "f_round": ((1.2345,), round_half_away),
    "f_sqrt": ((SUM_OF_SQUARES,), math.sqrt),
}
"""Each routine's charged operands (its listing's header) and the operation."""


def expected_bits(name: str, operands: tuple[float, ...]) -> int:
    """The correctly rounded float32: the operation in double on the float32-rounded
    operands, rounded once to float32 (exact for +, x, / and sqrt, and roundf is exact)."""
    return float_bits(CHARGED[name][1](*(f32(x) for x in operands)))


def copy_listings(tmp_path):
    """Every listing copied into tmp_path, so that includes resolve there."""
    for listing in LISTINGS.glob("*.asm"):
        shutil.copy(listing, tmp_path)
    return tmp_path


def write(tmp_path, text: str) -> None:
    (tmp_path / "body.asm").write_text(text, encoding="utf-8")


@pytest.mark.parametrize("name", CHARGED)
def test_a_charged_path_computes_the_correctly_rounded_float(name):
    operands = CHARGED[name][0]
    state = execute(name, float_args(*operands))
    assert result_bits(state) == expected_bits(name, operands)
    assert len(state.visited) == count(name).instructions
    assert state.sp == STACK_TOP and not state.calls       # CALL ... RET, the stack balanced


def test_the_float_helpers_and_the_charged_operands_as_the_headers_give_them():
    assert float_args(1.234, 5.678) == {"RL0": 0x3F9DF3B6, "RL2": 0x40B5B22D}
    assert float_args(1.2345) == {"RL0": 0x3F9E0419}
    assert float_bits(SUM_OF_SQUARES) == 0x42070CBD
    assert [expected_bits(n, CHARGED[n][0]) for n in CHARGED] == [
        0x40DD2F1A, 0x40E0367E, 0x3E5E8BC4, 0x3F800000, 0x40B9EFFD]


@pytest.mark.parametrize("name, operands", [
    ("f_add", (2.881, 11.39)), ("f_add", (1.463, 4.904)), ("f_mul", (1.234, 0.5678)),
    ("f_mul", (2.5, 1.5)), ("f_div", (0.862, 7.188)), ("f_div", (2.939, 7.728)),
    ("f_round", (12.345,)), ("f_round", (-2.5,)),
])
def test_other_operands_on_the_same_path_compute_the_correctly_rounded_float(name, operands):
    assert result_bits(execute(name, float_args(*operands))) == expected_bits(name, operands)


FLIPS = [(name, said) for name in CHARGED for said in ("taken", "not taken")
         if f"{{{said}}}" in (LISTINGS / f"{name}.asm").read_text(encoding="utf-8")]


@pytest.mark.parametrize("name, said", FLIPS)
def test_a_flipped_annotation_raises_naming_its_line(tmp_path, name, said):
    directory = copy_listings(tmp_path)
    path = directory / f"{name}.asm"
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    index = next(i for i, line in enumerate(lines) if f"{{{said}}}" in line)
    flipped = "not taken" if said == "taken" else "taken"
    lines[index] = lines[index].replace(f"{{{said}}}", f"{{{flipped}}}")
    path.write_text("".join(lines), encoding="utf-8")
    count(name, directory)                                  # the counter reads it still
    with pytest.raises(ExecutionError) as e:
        execute(name, float_args(*CHARGED[name][0]), directory)
    assert str(e.value).startswith(f"{name}.asm:{index + 1}: ")
    assert f"the listing says {flipped}, the data says {said}" in str(e.value)


@pytest.mark.parametrize("name, operands, line", [
    ("f_add", (1.234, 0.5678), "BGE   x_larger {not taken}"),   # x is the larger now
    ("f_add", (1.234, -5.678), "BN    subtract {not taken}"),   # a subtraction
    ("f_mul", (1.234, 0.0), "BEQ   y_zero {not taken}"),
    ("f_div", (5.678, 1.234), "BHS   n_not_below {not taken}"),
    ("f_round", (0.2345,), "BLT   below_one {not taken}"),
    ("f_sqrt", (4.0,), "BEQ   even {not taken}"),
])
def test_other_operands_make_an_annotation_wrong(tmp_path, name, operands, line):
    directory = copy_listings(tmp_path)
    with pytest.raises(ExecutionError, match=rf"^{name}\.asm:\d+: ") as e:
        execute(name, float_args(*operands), directory)
    assert line in str(e.value) and "the data says taken" in str(e.value)


def test_the_model_runs_every_form_the_float_library_uses():
    assert set(HANDLERS) <= set(cycles.FORMS)
    used = {step.form for p in LISTINGS.glob("f_*.asm") for step in count(p.stem).steps}
    assert used <= set(HANDLERS)


def test_moves_into_a_swaps_and_bytes_as_mame_has_them(tmp_path):
    write(tmp_path, """
        MOVW  A, #0x1234
        MOVW  A, #0x5678                ; AL moves to AH first
        SWAP                            ; AL's bytes
        SWAPW                           ; AH and AL
        MOV   A, R1                     ; RW4's high byte; AL moves to AH
        CWBNE A, #0x00AB, away {not taken}
        MOVL  RL3, A
""")
    state = execute("body", {"RW4": 0xAB00}, tmp_path)
    assert state.a == 0x123400AB and state.rw[6:] == [0x00AB, 0x1234]
    assert len(state.visited) == 7


def test_a_taken_branch_must_land_where_the_path_goes_on(tmp_path):
    write(tmp_path, "        MOVW  A, #0\n        BEQ   there {taken}\nthere:\n"
                    "        MOVW  A, #2\n")
    assert len(execute("body", {}, tmp_path).visited) == 3
    write(tmp_path, "        MOVW  A, #0\n        BEQ   there {taken}\n        MOVW  A, #1\n"
                    "there:\n        MOVW  A, #2\n")
    with pytest.raises(ExecutionError, match=r"^body\.asm:2: BEQ") as e:
        execute("body", {}, tmp_path)
    assert "body.asm:3" in str(e.value) and "would not run" in str(e.value)


@pytest.mark.parametrize("text, regs, says", [
    ("MOVL  A, RL0\nLSRL  A, R0 {bits 2}", {"RW4": 3}, "R0 is 3, the listing charges {bits 2}"),
    ("MOV   ILM, #7", {}, "no model of 'MOV ILM,#imm'"),
    ("CALL  body\nPUSHW A\nRET", {}, "the stack is unbalanced"),
    ("RET", {}, "RET with no CALL"),
    ("MOVW  A, @RW1+4", {"RW1": 0x0200}, "0x0204, which nothing wrote"),
    ("MOVW  A, @RW1", {"RW1": 0x0201}, "0x0201, an odd address"),
    ("MOVW  A, @RW1+disp16:nowhere", {}, "no table nowhere"),
])
def test_what_the_model_cannot_run_raises_naming_the_line(tmp_path, text, regs, says):
    write(tmp_path, "; first line\n" + text + "\n")
    with pytest.raises(ExecutionError, match=rf"^body\.asm:{text.count(chr(10)) + 2}: ") as e:
        execute("body", regs, tmp_path)
    assert says in str(e.value)
