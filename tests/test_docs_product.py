"""The docs describe the product as it is now (issue 44): counts in the docs that match the
code."""
from __future__ import annotations

import re
from pathlib import Path

from hil.cli.trace_digests import RUNS

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"

NUMBERS = {"seven": 7, "eight": 8, "nine": 9, "ten": 10, "eleven": 11, "twelve": 12}


def test_architecture_counts_the_trace_digests_the_suite_checks():
    text = (DOCS / "architecture.md").read_text(encoding="utf-8")
    said = re.findall(r"each of (\w+) seeded", text) + re.findall(r"runs the same (\w+)\b", text)
    assert said, "docs/architecture.md no longer says how many trace digests there are"
    assert {NUMBERS.get(w, w) for w in said} == {len(RUNS)}, (said, len(RUNS))
