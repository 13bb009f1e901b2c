"""docs/cpu.md's seeded figures are what their commands print today. They are the same on any
machine (a seed, the CPU model's cycle table), so a figure that differs is stale. Each is read
from the doc, not written here again: a doc edited without the code, or the code without the
doc, fails."""
from __future__ import annotations

import json
import re

import pytest

from hil.cli import main
from paths import ROOT

DOC = (ROOT / "docs" / "cpu.md").read_text(encoding="utf-8")


def _row(figure: str) -> str:
    """The value cell of the Measured table's row ``figure``."""
    m = re.search(rf"^\| {re.escape(figure)} \| (.+?) \|$", DOC, re.M)
    assert m, f"docs/cpu.md has no row {figure!r}"
    return m.group(1)


def _sim(capsys, *args: str) -> str:
    assert main(["sim", *args, "--no-progress"]) == 0
    return capsys.readouterr().out


def test_the_measured_cpu_load_and_dispatcher_latency_are_todays(capsys):
    """``rprs sim --robots 0,1,2,3 --duration 60 --seed 1 --can --load 1 --cpu-report``: the
    Measured table's load per child (and R1's handler shares), its UART overruns and frame
    gaps, and the dispatcher latency over its orders."""
    assert "`rprs sim --robots 0,1,2,3 --duration 60 --seed 1 --can --load 1 --cpu-report`" \
        in DOC
    out = _sim(capsys, "--robots", "0,1,2,3", "--duration", "60", "--seed", "1", "--can",
               "--load", "1", "--cpu-report")
    load = _row("CPU load per child")
    loads = re.match(r"(R1 [\d.]+ %, R2 [\d.]+ %, R3 [\d.]+ %)", load)
    assert loads and f"CPU load (MB90F549 model): {loads.group(1)};" in out, (load, out)
    # R1's shares: "UART0 RX 0.66 % at 560 bytes/s", "main loop 1.64 %", ...
    r1 = out.split("R1 CPU budget")[1].split("R2 CPU budget")[0]
    shares = re.findall(r"(UART0 RX|main loop|CAN0 RX|UART0 TX) ([\d.]+) %", load)
    assert len(shares) == 4
    for name, pct in shares:
        row = next(ln for ln in r1.splitlines() if ln.strip().startswith(name))
        assert pct in row.split(), (name, pct, row)
    assert "UART overruns: 0; gaps in frames sent: 0" in out
    assert _row("UART overruns").startswith("0; ") and _row("gaps in frames sent").startswith("0;")
    found = re.search(r"SOF \((\d+) orders\)", DOC)
    assert found, "docs/cpu.md has no dispatcher latency row"
    orders = found.group(1)
    lat = _row(f"dispatcher latency, radio End to the order's first CAN frame's SOF "
               f"({orders} orders)")
    m = re.match(r"min ([\d.]+) us .*median ([\d.]+) us, max ([\d.]+) us", lat)
    assert m, lat
    assert (f"over {orders} orders: min {m.group(1)} us, median {m.group(2)} us, "
            f"max {m.group(3)} us") in out, out


@pytest.mark.parametrize("cycles, delivered", [(20000, "109"), (33000, "108")])
def test_a_transmit_handler_slower_than_a_byte_keeps_the_ring_as_the_doc_says(
        capsys, tmp_path, cycles, delivered):
    """``rprs sim --robots 0,1,2 --duration 30 --seed 1 --load 1 --cpu estimated --cpu-costs
    slow.toml``: the doc's messages delivered of those submitted, and the gaps, for 20,000
    cycles a byte; the same at 33,000; no membership change after the ring formed."""
    m = re.search(r"slow\.toml` delivers (\d+) of (\d+) messages \(one pending at the end\), "
                  r"with ([\d,]+) gaps and no\s+membership change after the ring formed "
                  r"\(33,000 cycles: (\d+) of (\d+), two pending\)", DOC)
    assert m, "docs/cpu.md's slow.toml sentence is not where this test reads it"
    costs = tmp_path / "slow.toml"
    costs.write_text(f"[costs]\nuart_tx_byte = {cycles}\n")
    out = json.loads(_sim(capsys, "--robots", "0,1,2", "--duration", "30", "--seed", "1",
                          "--load", "1", "--cpu", "estimated", "--cpu-costs", str(costs),
                          "--json"))
    said = (m.group(1), m.group(2)) if cycles == 20000 else (m.group(4), m.group(5))
    assert said[0] == delivered
    assert (str(out["delivered"]), str(out["submitted"])) == said, out
    assert out["submitted"] - out["delivered"] == out["pending"] == (1 if cycles == 20000
                                                                     else 2)
    if cycles == 20000:
        assert f"{sum(out['cpu_tx_gaps'].values()):,}" == m.group(3)
    assert [c for c in out["membership_changes"] if c["t"] > 3 * 16_000_000] == []
