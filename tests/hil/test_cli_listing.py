"""``rprs listing``: the handler rows, one listing instruction by instruction, a user's own
listing, and the mistakes a user makes (one line, status 2, no traceback)."""
from __future__ import annotations

import json

from firmware_model.cycle_costs import DEFAULT_COSTS
from firmware_model.isa.listing import count
from hil.cli import main


def test_every_handler_row_with_its_count(capsys):
    assert main(["listing", "--json"]) == 0
    rows = {r["row"]: r for r in json.loads(capsys.readouterr().out)["rows"]}
    assert set(rows) == {n for n, c in DEFAULT_COSTS.rows() if c.source.startswith("listing:")}
    c = count("can_rx")
    assert rows["can_rx"] == {"row": "can_rx", "cycles": c.cycles, "worst": c.worst,
                              "instructions": c.instructions, "us": round(c.cycles / 16, 2)}
    assert main(["listing"]) == 0
    table = capsys.readouterr().out
    line = next(x for x in table.splitlines() if x.startswith("can_rx "))
    assert line.split() == ["can_rx", str(c.cycles), f"{c.cycles / 16:.2f}", str(c.worst),
                            str(c.instructions)]


def test_one_listing_instruction_by_instruction_with_each_source(capsys):
    assert main(["listing", "uart_tx_byte"]) == 0
    out = capsys.readouterr().out.splitlines()
    c = count("uart_tx_byte")
    assert len(out) == c.instructions + 1
    assert out[0].split()[:3] == ["MOV", "RP,", "#BANK"] and "case 0x0A" in out[0]
    assert out[-1].startswith(f"uart_tx_byte: {c.cycles} cycles")
    assert main(["listing", "uart_tx_byte", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert sum(s["cycles"] for s in doc["steps"]) == doc["cycles"] == c.cycles


def test_a_listing_of_your_own(tmp_path, capsys):
    (tmp_path / "enter.asm").write_text("MOV RP, #2\n")
    mine = tmp_path / "mine.asm"
    mine.write_text(".include enter\nMOVW A, I:SIDR0\nMULUW A\n")
    assert main(["listing", "--file", str(mine)]) == 0
    assert capsys.readouterr().out.splitlines()[-1].startswith("mine: 16 cycles")


def test_mistakes_are_one_line_and_status_2(tmp_path, capsys):
    bad = tmp_path / "bad.asm"
    bad.write_text("; mine\nBNE away\n")
    for argv, says in ((["listing", "nothing"], "no listing nothing.asm"),
                       (["listing", "--file", str(tmp_path / "x.asm")], "no listing"),
                       (["listing", "--file", str(tmp_path)], "a listing is a NAME.asm file"),
                       (["listing", "--file", str(bad)], "bad.asm:2: BNE away: BNE is a "
                                                         "conditional branch")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("rprs: error: ") and says in err, err
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_rprs_sim_runs_a_handler_listing_of_your_own(tmp_path, capsys):
    (tmp_path / "rx.asm").write_text("MOV A, I:SIDR0\n.repeat 20\nMULUW A\n.endr\n")
    costs = tmp_path / "mine.toml"
    costs.write_text('[listings]\nuart_rx_byte = "rx.asm"\n')
    argv = ["sim", "--robots", "1,2", "--duration", "3", "--seed", "1", "--cpu-report",
            "--json", "--no-progress"]
    assert main([*argv, "--cpu-costs", str(costs)]) == 0
    report = json.loads(capsys.readouterr().out)["cpu_report"]["1"]
    rx = next(h for h in report["handlers"] if h["handler"] == "UART0 RX")
    assert rx["costs"]["uart_rx_byte"] == {"cycles": 3 + 20 * 11, "source": "listing"}
    (tmp_path / "rx.asm").write_text("BNE away\n")
    assert main([*argv, "--cpu-costs", str(costs)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rprs: error: ") and "rx.asm:1: BNE away" in err
    assert "Traceback" not in err
