"""Where the project's files are, for tests in any folder of ``tests/``: ``ROOT`` the
checkout, ``TESTS`` the tests' own folder (its shared helpers and ``data/``)."""
from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
