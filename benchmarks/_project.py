"""The first thing every benchmark does when run as a script: make sure this Python has the
project and its dependencies, else say in one line what to run instead (no traceback).

Not a benchmark; ``python benchmarks/NAME.py`` puts this directory first on ``sys.path``.
"""
from __future__ import annotations

import importlib.util
import os
import sys

PROJECT = ("firmware_model", "hil", "can_bus", "construct", "can", "cantools", "serial",
           "rich")
"""Modules a benchmark of the project imports: the project's packages and its dependencies
(pyproject.toml), by their import names."""


def missing(modules: tuple[str, ...]) -> list[str]:
    """The modules of ``modules`` this Python cannot import (found without importing them)."""
    out = []
    for m in modules:
        try:
            found = importlib.util.find_spec(m) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            out.append(m)
    return out


def require_project(modules: tuple[str, ...] = PROJECT, extra: str = "") -> None:
    """Exit with status 2 and one line on stderr if this Python lacks any of ``modules``;
    ``extra``: the pip extra that adds them (``bench``), when they are not the project's own."""
    gone = missing(modules)
    if not gone:
        return
    script = os.path.relpath(sys.argv[0]) if sys.argv and sys.argv[0] else "benchmarks"
    install = f".venv/bin/pip install -e '.[{extra}]'" if extra else ".venv/bin/pip install -e ."
    print(f"{script}: this Python ({sys.executable}) has no {', '.join(gone)}: run it with "
          f"the project's venv, `.venv/bin/python {script}` (or `. .venv/bin/activate` first; "
          f"the venv: python3 -m venv .venv && {install})", file=sys.stderr)
    sys.exit(2)
