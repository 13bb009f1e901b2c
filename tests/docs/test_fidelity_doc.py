"""docs/fidelity.md is kept true: every figure in its table is what the code holds.

Each row that states a figure names, in its last column, Python expressions (a constant, a
call, or a ``probe`` measurement below); each is evaluated and must equal the row's figure. A
row without a figure names the tests that hold its behaviour, and they must exist. Every row
says exact, approximate or assumed, the summary counts them, and every row of the CPU cost
table is in some row. The checker itself is tested: a figure whose first number is changed
is caught, in every row.
"""
from __future__ import annotations

import ast
import importlib
import math
import re
from collections import Counter

import pytest

from can_bus.bits import BitTiming
from can_bus.bus import CanBus
from can_bus.frames import CanFrame
from firmware_model.cycle_costs import DEFAULT_COSTS
from firmware_model.mcu.scheduler import Scheduler

from can_testbed import Node
from paths import ROOT

DOC = ROOT / "docs" / "fidelity.md"
HEADER = "| behaviour | figure | model | source | fidelity | check |"
GRADES = ("exact", "approximate", "assumed")
NO_FIGURE = "—"


class probe:
    """Measurements of the model for figures that are a condition in the code."""

    @staticmethod
    def _walk(steps: list[tuple[str, int]]) -> list[tuple[int, str]]:
        """A transmitter's (TEC, error state) after each of its errors and successes on the
        bus model: ("fail", n) is n attempts failing with a bit error (TEC + 8 each) and then
        one frame sent (TEC - 1), ("ok", n) is n frames sent."""
        sched = Scheduler()
        bus = CanBus(sched, BitTiming())
        seen: list[tuple[int, str]] = []

        class Sender(Node):
            def note(self):
                s = bus.status(self)
                seen.append((s.tec, s.state.value))

            def on_error(self, ev):
                super().on_error(ev)
                self.note()

            def on_tx_done(self, frame, end):
                super().on_tx_done(frame, end)
                self.note()

            def on_state_change(self, old, new, tick):
                super().on_state_change(old, new, tick)
                self.note()

        a = Sender("a")
        bus.attach(a)
        bus.attach(Node("b"))
        frame = CanFrame(0x123, b"\x11\x22")
        for kind, n in steps:
            if kind == "fail":
                bus.inject_bit_error(a, count=n)
            for _ in range(n if kind == "ok" else 1):
                bus.request(a, frame)
            sched.run_until(sched.now + 20_000_000)
        return seen

    @staticmethod
    def tec_entering(state: str) -> int:
        """The least TEC at which the bus model has a transmitter in ``state``
        ("error-passive", "bus-off"), to the unit: TEC climbs by 8 on an error and falls by
        1 on a frame sent, so the walks go up and then down through every value below 160
        (error passive), and reach each of 248-271 from below (bus off)."""
        if state == "error-passive":
            walks = [[("fail", 20), ("ok", 159)]]
        else:
            walks = [[("fail", 31), ("ok", d), ("fail", 3)] for d in range(8)]
        return min(tec for w in walks for tec, s in probe._walk(w) if s == state)

    @staticmethod
    def bus_off_tec_byte() -> int:
        """RTEC's TEC byte (bits 15-8) of a controller driven bus-off by bit errors on its
        frame, read while it is bus-off."""
        from can_bus.transceiver import Transceiver82C250
        from firmware_model.mcu.can_controller import CanController
        sched = Scheduler()
        bus = CanBus(sched, BitTiming())
        a, b = CanController(sched, name="A"), CanController(sched, name="B")
        xa = Transceiver82C250(bus, a, name="XA")
        Transceiver82C250(bus, b, name="XB")
        a.start()
        b.start()
        bus.inject_bit_error(xa, count=32)
        a.configure_tx(0, 0x123)
        a.transmit(0, b"\x11\x22")
        sched.run_until(1_000_000)
        assert a.bus_off, "the probe's controller did not go bus-off"
        return a.RTEC >> 8

    @staticmethod
    def least(field: str, prescaler: int) -> int:
        """The smallest ``field`` (tseg1 or tseg2, quanta) a bit timing with ``prescaler``
        ticks a quantum may have. The other fields are roomy and the clock slow (4 MHz), so
        only the controller's BTR conditions can refuse it, not the 1 Mbit/s limit."""
        base = {"prescaler": prescaler, "tseg1": 11, "tseg2": 8, "sjw": 1,
                "tick_hz": 4_000_000}
        for value in range(1, 17):
            try:
                BitTiming(**{**base, field: value})
            except ValueError:
                continue
            return value
        raise AssertionError(f"no {field} accepted")


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split(" | ")]


def _rows(text: str) -> list[dict[str, str]]:
    lines = text.splitlines()
    start = lines.index(HEADER)
    names = _cells(HEADER)
    rows = []
    for n, line in enumerate(lines[start + 2:], start + 3):
        if not line.startswith("|"):
            break
        cells = _cells(line)
        assert len(cells) == len(names), f"docs/fidelity.md:{n}: {len(cells)} cells: {line}"
        rows.append({"line": str(n), **dict(zip(names, cells))})
    return rows


def _summary(text: str) -> dict[str, int]:
    lines = text.splitlines()
    start = lines.index("| fidelity | rows |")
    out = {}
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        grade, count = _cells(line)
        out[grade] = int(count)
    return out


def figure_value(cell: str):
    """The figure a cell states: its leading tuple or number (thousands may be grouped with
    spaces: "16 000 000"); what follows (units, words) is for the reader."""
    if cell.startswith("("):
        depth = 0
        for i, ch in enumerate(cell):
            depth += {"(": 1, ")": -1}.get(ch, 0)
            if depth == 0:
                return ast.literal_eval(cell[:i + 1])
        raise ValueError(f"unbalanced figure {cell!r}")
    m = re.match(r"0x[0-9A-Fa-f]+|\d{1,3}(?: \d{3})+(?:\.\d+)?|\d+(?:\.\d+)?(?:e-?\d+)?", cell)
    if m is None:
        raise ValueError(f"no figure at the start of {cell!r}")
    return ast.literal_eval(m.group(0).replace(" ", ""))


def _checks(cell: str) -> list[str]:
    return re.findall(r"`([^`]+)`", cell)


def evaluate(expr: str):
    """Evaluate a check expression, importing the modules its dotted names go through."""
    tree = ast.parse(expr, mode="eval")
    for node in ast.walk(tree):
        chain = []
        while isinstance(node, ast.Attribute):
            chain.append(node.attr)
            node = node.value
        if isinstance(node, ast.Name) and node.id in ("firmware_model", "can_bus"):
            parts = [node.id, *reversed(chain)]
            for i in range(2, len(parts) + 1):
                try:
                    importlib.import_module(".".join(parts[:i]))
                except ModuleNotFoundError:
                    break
    namespace = {"firmware_model": importlib.import_module("firmware_model"),
                 "can_bus": importlib.import_module("can_bus"), "probe": probe}
    return eval(compile(tree, str(DOC), "eval"), namespace)


def same(figure, value) -> bool:
    if isinstance(figure, tuple):
        return (isinstance(value, (tuple, list)) and len(value) == len(figure)
                and all(same(f, v) for f, v in zip(figure, value)))
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return math.isclose(figure, value, rel_tol=1e-9, abs_tol=0.0)


def mismatches(rows: list[dict[str, str]]) -> list[str]:
    """Rows whose figure some check does not give, each with what the code holds."""
    bad = []
    for row in rows:
        if row["figure"] == NO_FIGURE:
            continue
        figure = figure_value(row["figure"])
        for expr in _checks(row["check"]):
            value = evaluate(expr)
            if not same(figure, value):
                bad.append(f"docs/fidelity.md:{row['line']}: {row['behaviour'][:50]!r} says "
                           f"{figure!r}, {expr} is {value!r}")
    return bad


def bumped(figure):
    """The figure with its first number changed by one."""
    if isinstance(figure, tuple):
        return (bumped(figure[0]), *figure[1:])
    return figure + 1 if isinstance(figure, int) else figure * 1.5


ROWS = _rows(DOC.read_text(encoding="utf-8"))


def test_every_figure_is_what_the_code_holds():
    assert len(ROWS) >= 40
    assert not mismatches(ROWS), "\n".join(mismatches(ROWS))


def test_a_figure_changed_by_one_fails_the_check_in_every_row():
    """So no row's check is one that cannot fail."""
    figure_rows = [r for r in ROWS if r["figure"] != NO_FIGURE]
    assert len(figure_rows) >= 35
    for row in figure_rows:
        changed = bumped(figure_value(row["figure"]))
        assert not any(same(changed, evaluate(e)) for e in _checks(row["check"])), row["line"]


def test_a_figure_row_names_expressions_and_a_behaviour_row_names_existing_tests():
    for row in ROWS:
        checks = _checks(row["check"])
        assert checks, f"docs/fidelity.md:{row['line']}: no check"
        tests = [c for c in checks if "::" in c]
        if row["figure"] == NO_FIGURE:
            assert tests == checks, f"docs/fidelity.md:{row['line']}: name the tests"
            for ref in tests:
                path, name = ref.split("::")
                source = (ROOT / path).read_text(encoding="utf-8")
                assert re.search(rf"^def {re.escape(name)}\(", source, re.M), ref
        else:
            assert not tests, f"docs/fidelity.md:{row['line']}: a figure needs an expression"


def test_every_row_is_graded_sourced_and_names_files_that_exist():
    for row in ROWS:
        where = f"docs/fidelity.md:{row['line']}"
        grade = re.match(r"\w+", row["fidelity"])
        assert grade and grade.group(0) in GRADES, f"{where}: fidelity {row['fidelity']!r}"
        if grade.group(0) != "exact":
            assert ":" in row["fidelity"], f"{where}: say why it is {grade.group(0)}"
        assert row["source"], f"{where}: no source (write 'none' and why)"
        files = re.findall(r"`([\w/]+\.py)`", row["model"])
        assert files, f"{where}: name the model's file"
        for path in files:
            assert (ROOT / path).is_file(), f"{where}: {path}"


def test_the_summary_counts_the_rows():
    counts = Counter(re.match(r"\w+", r["fidelity"]).group(0) for r in ROWS)
    assert _summary(DOC.read_text(encoding="utf-8")) == {g: counts[g] for g in GRADES}


def test_every_cycle_cost_is_in_the_table():
    checks = " ".join(r["check"] for r in ROWS)
    missing = [n for n in DEFAULT_COSTS.names() if not re.search(rf"\b{n}\b", checks)]
    assert not missing, missing


def test_the_page_is_linked():
    assert "(docs/fidelity.md)" in (ROOT / "README.md").read_text(encoding="utf-8")
    assert "(fidelity.md)" in (ROOT / "docs" / "cpu.md").read_text(encoding="utf-8")


@pytest.mark.parametrize("cell, value", [
    ("16 000 000 Hz", 16_000_000), ("1664 ticks", 1664), ("7.6e-3 us/kOhm", 7.6e-3),
    ("3e-6 s", 3e-6), ("(0x0001, 0x0004) bits", (1, 4)), ("((2, 3, 0), (2, 1, 7))",
                                                         ((2, 3, 0), (2, 1, 7))),
    ("1 600 000 ticks (100 ms)", 1_600_000), ("1.0 m", 1.0),
])
def test_figures_are_read_as_written(cell, value):
    assert figure_value(cell) == value
