"""The seeded tables of docs/performance.md are what their benchmarks print today: they are
the same on any machine, so a row that differs is a stale figure (the checksum and peer-MAC
tables once drifted by a few messages each, unnoticed)."""
from __future__ import annotations

import subprocess
import sys

import pytest
from paths import ROOT

DOC = (ROOT / "docs" / "performance.md").read_text()


def _rows(script: str) -> list[str]:
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / script)], cwd=ROOT,
                         capture_output=True, text=True, check=True, timeout=600).stdout
    return [line for line in out.splitlines() if line.startswith("| ") and
            not line.startswith(("| BER |", "| MAC |"))]


def test_the_checksum_table_is_todays():
    """docs/performance.md's table, and docs/mac.md's copy of it."""
    rows = _rows("checksum_effect.py")
    assert len(rows) == 6
    mac = (ROOT / "docs" / "mac.md").read_text()
    stale = [r for r in rows if r not in DOC or r not in mac]
    assert not stale, stale


@pytest.mark.slow
def test_the_peer_mac_rows_shown_are_todays():
    """The doc shows some of the rows (nine of 18 peer rows and the rotational one): each
    shown is printed today, and at least nine are shown. docs/peer-macs.md shows every row
    (its copy was stale in seven rows while this one was not)."""
    rows = _rows("peer_macs.py")
    shown = [r for r in rows if any(line.startswith(" | ".join(r.split(" | ")[:2]) + " |")
                                    for line in DOC.splitlines())]
    assert len(shown) >= 9, shown
    stale = [r for r in shown if r not in DOC]
    assert not stale, stale
    peer = (ROOT / "docs" / "peer-macs.md").read_text()
    assert len(rows) == 19, rows
    stale = [r for r in rows if r not in peer]
    assert not stale, stale


@pytest.mark.slow
def test_the_father_pair_table_is_todays():
    """docs/guarantees.md's seeded father-pair row (200 runs, a few minutes of CPU)."""
    rows = [r for r in _rows("father_pair.py") if not r.startswith("| seeded")]
    assert len(rows) == 1
    assert rows[0] in (ROOT / "docs" / "guarantees.md").read_text(), rows
