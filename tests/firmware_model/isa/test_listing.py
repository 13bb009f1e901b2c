"""The instruction listings and their counter: figures worked by hand, the errors a listing
writer gets, and every handler row of the cycle-cost table equal to its listing's count."""
from __future__ import annotations

import pytest

from firmware_model.cycle_costs import DEFAULT_COSTS
from firmware_model.isa import cycles
from firmware_model.isa.listing import LISTINGS, ListingError, count, operand_kind

HANDLER_ROWS = ("uart_rx_byte", "mac_frame", "mac_timer", "uart_tx_byte", "uart_tx_done",
                "content_byte", "command", "can_frame_out", "can_rx", "can_tx", "can_status",
                "dispatcher_timer")
FLOAT_ROWS = ("f_add", "f_mul", "f_div", "f_sin", "f_cos", "f_atan2", "f_acos", "f_hypot",
              "f_round")
LISTED_ROWS = HANDLER_ROWS + FLOAT_ROWS


def write(tmp_path, name, text):
    (tmp_path / f"{name}.asm").write_text(text, encoding="utf-8")


def test_a_listing_worked_by_hand(tmp_path):
    write(tmp_path, "enter", "        MOV RP, #1      ; 2\n")
    write(tmp_path, "body", """
; a comment line, and a label below
        .include enter
start:
        MOV   A, I:SSR0                 ; 3
        BNE   away {not taken}          ; 3
        .repeat 3
        MOVW  A, @RW1+2 {can}           ; 5 each
        DWBNZ RW6, start {taken}        ; 7 each
        .endr
        BEQ   away {taken}              ; 4
        PUSHW (RW0, RW1, RW2)           ; 29 + 3 x 3
        POPW  (RW0, RW1, RW2)           ; 3 x 3
        MULUW A                         ; 11
        LSRL  A, R0 {bits 3}            ; 6 + 3
""")
    c = count("body", tmp_path)
    assert c.cycles == 2 + 3 + 3 + 3 * (5 + 7) + 4 + 38 + 9 + 11 + 9
    assert c.instructions == 14
    # the worst case: +2 a fetch across a word boundary, +64 a CAN buffer access
    assert c.worst == c.cycles + 2 * 14 + 64 * 3
    assert [s.form for s in c.steps[:3]] == ["MOV RP,#imm", "MOV A,io", "BNE rel"]


@pytest.mark.parametrize("text, says", [
    ("BNE away", "say {taken} or {not taken}"),
    ("LSRL A, R0", "shifts by a count: say {bits N}"),
    ("LSRL A, R0 {bits two}", "shifts by a count: say {bits N}"),
    ("LSRW A {bits 2}", "takes no {bits N}"),
    ("MOVW A, RW0 {taken}", "no conditional branch"),
    ("MOVW A, @RW9+2", "no addressing mode"),
    ("FROB A", "'FROB A' is not in the instruction table"),
    ("CMP A, S:x", "'CMP A,dir' is not in the instruction table"),
    (".repeat\nNOP\n.endr", ".repeat needs a count"),
    (".repeat 2\nNOP", ".repeat without .endr"),
    ("NOP\n.endr", ".endr without .repeat"),
    (".include body", "includes itself"),
    (".include nowhere", "no listing nowhere.asm"),
])
def test_a_listing_the_counter_cannot_read_names_its_line(tmp_path, text, says):
    write(tmp_path, "body", "; first line\n" + text + "\n")
    with pytest.raises(ListingError, match="body.asm|nowhere.asm") as e:
        count("body", tmp_path)
    assert says in str(e.value)
    if "include" not in text and "without" not in says:
        assert "body.asm:2" in str(e.value)


@pytest.mark.parametrize("op, kind", [
    ("A", "A"), ("#0x30", "#imm"), ("R3", "Ri"), ("RW7", "RWi"), ("RL1", "RLi"),
    ("I:SSR0", "io"), ("S:x", "dir"), ("I:OCS0:5", "io:bp"), ("S:f:1", "dir:bp"),
    ("TREQR:3", "addr16:bp"), ("@RW2+6", "@RWi+disp8"), ("@RW1", "@RWj"),
    ("@RW3+", "@RWj+"), ("@A", "@A"), ("(RW0,RW1)", "rlst"), ("label", "name"),
])
def test_operand_kinds(op, kind):
    assert operand_kind(op) == kind


def test_the_table_agrees_with_the_manual_where_its_rows_are_at_hand():
    for form, manual in cycles.MANUAL.items():
        assert cycles.FORMS[form].cycles == manual, form
    assert cycles.FORMS["MULUW A"].cycles == DEFAULT_COSTS.mul16.cycles
    assert cycles.FORMS["DIVUW A,RWi"].cycles == DEFAULT_COSTS.div32.cycles
    assert cycles.FORMS["RETI"].cycles == DEFAULT_COSTS.reti.cycles


def test_every_conditional_branch_costs_at_least_as_much_taken():
    for form, f in cycles.FORMS.items():
        if f.taken is not None:
            assert f.taken >= f.cycles, form


@pytest.mark.parametrize("row", LISTED_ROWS)
def test_each_listed_row_is_its_listings_count(row):
    c = count(row)
    cost = getattr(DEFAULT_COSTS, row)
    assert cost.cycles == c.cycles > 0
    assert cost.source.startswith(f"listing: firmware_model/isa/listings/{row}.asm, "
                                  f"{c.instructions} instructions")
    assert f"worst {c.worst}" in cost.good_for
    assert c.worst > c.cycles


def test_every_listing_file_is_a_row_or_included():
    assert {n for n, c in DEFAULT_COSTS.rows() if c.source.startswith("listing:")} == \
        set(LISTED_ROWS)
    names = {p.stem for p in LISTINGS.glob("*.asm")}
    assert names == set(LISTED_ROWS) | {"isr_enter", "f_sqrt", "f_reduce_pio2", "job_deadline"}


INTERRUPT_HANDLERS = {"uart_rx_byte", "uart_tx_byte", "uart_tx_done", "mac_timer", "can_rx",
                      "can_tx", "can_status", "dispatcher_timer"}
"""The rows that are a whole interrupt handler's body; mac_frame is the tail of UART0 RX's,
the others run in the main loop."""


def test_interrupt_handlers_start_in_their_bank_and_leave_reti_to_its_row():
    for row in HANDLER_ROWS:
        text = (LISTINGS / f"{row}.asm").read_text(encoding="utf-8")
        isr = row in INTERRUPT_HANDLERS
        assert (".include isr_enter" in text) == isr, row
        assert ("RETI: charged from cycle_costs.py" in text) == isr, row
        code = [line.split(";")[0].split() for line in text.splitlines()]
        assert ["RETI"] not in code, row
