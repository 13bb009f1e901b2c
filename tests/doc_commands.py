"""What the docs' shell commands ask of a fresh machine (a helper for the tests, not a test)."""
from __future__ import annotations

import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def dirs_without_parent(pattern: str) -> tuple[int, list[str]]:
    """Every directory a docs command names with ``pattern`` (a regex whose group 1 is an
    absolute path), in README.md and docs/*.md: how many there are, and the lines of those
    whose parent neither exists anywhere (``/tmp``) nor is made by an earlier ``mkdir -p``
    of the same page (the hub and the ``rprs_unix`` bus make only the last directory)."""
    seen, bad = 0, []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        made = {"/tmp"}
        for line in page.read_text(encoding="utf-8").splitlines():
            for d in re.findall(r"mkdir -p (/\S+)", line):
                while d not in ("/", ""):
                    made.add(d.rstrip("/"))
                    d = os.path.dirname(d.rstrip("/"))
            for d in re.findall(pattern, line):
                seen += 1
                if os.path.dirname(d.rstrip("/")) not in made:
                    bad.append(f"{page.name}: {line.strip()}")
    return seen, bad
