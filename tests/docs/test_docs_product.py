"""The docs describe the product as it is now (issue 44): no dated development-log entries or
numbered work periods in the docs, the code or the tests (history lives in git), counts in
the docs that match the code, docs/performance.md short enough to read, and a glossary whose
references exist."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from trace_digests import RUNS
from paths import ROOT

DOCS = ROOT / "docs"

DIARY = re.compile(r"[Ss]ession [0-9]+|20[0-9]{2}-[0-9]{2}-[0-9]{2}")
"""A numbered work period or a calendar date."""

REAL_DATES = {
    ("firmware_model/radio/auth.py", "2026-01-01 00:00 UTC"),
    ("docs/protocol.md", "2026-01-01 00:00 UTC"),
    ("tests/hil/bench/test_stranger_robot.py", "2026-01-01 00:00 UTC"),
    ("tests/firmware_model/radio/test_auth.py", "2026-01-01 00:00 UTC"),
    # a key file's own epoch line (clause 54), and malformed ones
    ("tests/firmware_model/radio/test_auth.py", "2030-03-01"),
    ("tests/firmware_model/radio/test_auth.py", "2030-02-30"),
    ("tests/firmware_model/radio/test_auth.py", "2030-04-01"),
    # an epoch still to come, which a PC refuses to start with (clause 52)
    ("tests/firmware_model/radio/test_auth.py", "2099-01-01"),
    ("tests/hil/test_cli.py", "2099-01-01"),
}
"""Dates that are part of the product: the authenticated profile's freshness epoch, and the
epochs of key files in the tests."""

NUMBERS = {"seven": 7, "eight": 8, "nine": 9, "ten": 10, "eleven": 11, "twelve": 12,
           "sixteen": 16}


def _files() -> list[Path]:
    out = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
    for d in ("firmware_model", "can_bus", "hil", "tests", "benchmarks", "scripts"):
        out += sorted(p for p in (ROOT / d).rglob("*")
                      if p.suffix in (".py", ".md", ".sh", ".toml") and p.is_file())
    return out


def test_no_dated_log_entries_or_session_numbers():
    found = []
    for path in _files():
        rel = path.relative_to(ROOT).as_posix()
        if rel == "tests/docs/test_docs_product.py":
            continue
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for m in DIARY.finditer(line):
                if not any(rel == f and m.group(0) in real and real in line
                           for f, real in REAL_DATES):
                    found.append(f"{rel}:{n}: {line.strip()[:100]}")
    assert not found, "dated entries or session numbers (history lives in git):\n" + \
        "\n".join(found)


def test_architecture_counts_the_trace_digests_the_suite_checks():
    text = (DOCS / "architecture.md").read_text(encoding="utf-8")
    said = re.findall(r"each of (\w+) seeded", text) + re.findall(r"runs the same (\w+)\b", text)
    assert said, "docs/architecture.md no longer says how many trace digests there are"
    assert {NUMBERS.get(w, w) for w in said} == {len(RUNS)}, (said, len(RUNS))


def test_performance_page_is_at_most_300_lines():
    lines = (DOCS / "performance.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 300, len(lines)


def test_the_glossary_is_linked_and_its_references_exist():
    assert "(docs/glossary.md)" in (ROOT / "README.md").read_text(encoding="utf-8")
    text = (DOCS / "glossary.md").read_text(encoding="utf-8")
    protocol = (DOCS / "protocol.md").read_text(encoding="utf-8")
    clauses = {int(n) for n in re.findall(r"\*\*Clause (\d+)", protocol)}
    cited = set()
    for group in re.findall(r"clauses? ([\d, and-]+\d)", text):
        for a, b in re.findall(r"(\d+)(?:-(\d+))?", group):
            cited.update(range(int(a), int(b or a) + 1))
    assert cited and cited <= clauses, sorted(cited - clauses)
    for path in re.findall(r"`((?:hil|can_bus|firmware_model|tests|benchmarks|scripts)/[\w/.]+)`",
                           text):
        assert (ROOT / path).exists(), path
    for page in re.findall(r"\]\((\w[\w-]*\.md)\)", text):
        assert (DOCS / page).exists(), page


@pytest.mark.parametrize("page", ["performance.md", "fast-paths.md"])
def test_every_named_section_of_the_performance_pages_exists(page):
    """Code and docs point into docs/performance.md and docs/fast-paths.md by a section's
    title: each one is there."""
    text_of_page = (DOCS / page).read_text(encoding="utf-8")
    missing = []
    for path in _files():
        text = path.read_text(encoding="utf-8")
        for section in re.findall(rf'{re.escape(page)}\)?,\s*(?:#\s*)?"([^"]+)"', text):
            section = " ".join(section.split())
            if not re.search(rf"^#+ {re.escape(section)}$", text_of_page, re.M):
                missing.append(f"{path.relative_to(ROOT)}: {section!r}")
    assert not missing, missing
