"""The import rules of docs/architecture.md, checked on the source: ``can_bus`` is a CAN library
that stands alone (it imports neither ``firmware_model`` nor ``hil``), and ``firmware_model``
never imports ``hil``. Every import statement counts, including ones inside functions."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from can_bus.clock import DEFAULT_TICK_HZ
from firmware_model.timing import TICK_HZ

ROOT = Path(__file__).resolve().parent.parent
FORBIDDEN = {
    "can_bus": ("firmware_model", "hil"),
    "firmware_model": ("hil",),
}


def imported_packages(path: Path, package: str) -> set[tuple[int, str]]:
    """(line, top-level package) of every import in ``path``; relative imports resolve to
    ``package``."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out |= {(node.lineno, a.name.split(".")[0]) for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            top = package if node.level else (node.module or "").split(".")[0]
            out.add((node.lineno, top))
    return out


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_import_against_the_layering(package):
    files = sorted((ROOT / package).rglob("*.py"))
    assert files, f"no sources under {package}/"
    bad = [f"{f.relative_to(ROOT)}:{line} imports {top}"
           for f in files for line, top in imported_packages(f, package)
           if top in FORBIDDEN[package]]
    assert not bad, "\n".join(bad)


def test_the_checker_sees_a_forbidden_import(tmp_path):
    bad = tmp_path / "m.py"
    bad.write_text("def f():\n    from hil.world import World\n")
    assert (2, "hil") in imported_packages(bad, "firmware_model")


def test_the_firmware_clock_is_the_can_library_default():
    assert TICK_HZ == DEFAULT_TICK_HZ
