"""The import rules of docs/architecture.md, checked on the source: ``can_bus`` is a CAN library
that stands alone (it imports neither ``firmware_model`` nor ``hil``), ``firmware_model`` never
imports ``hil``, and the rooms of ``hil`` import only downwards: ``sim`` nothing of the others,
``bench`` only ``sim``, ``view`` ``sim`` and ``bench``, ``cli`` anything. Every import
statement counts, including ones inside functions; relative imports are resolved."""
from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

from can_bus.clock import DEFAULT_TICK_HZ
from firmware_model.timing import TICK_HZ

ROOT = Path(__file__).resolve().parent.parent
FORBIDDEN = {
    "can_bus": ("firmware_model", "hil"),
    "firmware_model": ("hil",),
    "hil/sim": ("hil.bench", "hil.view", "hil.cli", "hil.campaign"),
    "hil/bench": ("hil.view", "hil.cli", "hil.campaign"),
    "hil/view": ("hil.cli", "hil.campaign"),
    "hil/wireshark": ("hil.sim", "hil.bench", "hil.view", "hil.cli", "hil.campaign"),
}


def imported_modules(path: Path) -> set[tuple[int, str]]:
    """(line, dotted module) of every import in ``path`` (a file under ROOT); relative imports
    are resolved against the file's package."""
    package = list(path.relative_to(ROOT).parent.parts)
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out |= {(node.lineno, a.name) for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            out.add((node.lineno, mod))
            if not node.module:          # from . import x: x is a module of that package
                out |= {(node.lineno, f"{mod}.{a.name}") for a in node.names}
    return out


def _under(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


@pytest.mark.parametrize("room", sorted(FORBIDDEN))
def test_no_import_against_the_layering(room):
    files = sorted((ROOT / room).rglob("*.py"))
    assert files, f"no sources under {room}/"
    bad = [f"{f.relative_to(ROOT)}:{line} imports {mod}"
           for f in files for line, mod in imported_modules(f)
           for banned in FORBIDDEN[room] if _under(mod, banned)]
    assert not bad, "\n".join(bad)


def test_the_checker_sees_forbidden_imports(tmp_path, monkeypatch):
    pkg = tmp_path / "hil" / "sim"
    pkg.mkdir(parents=True)
    bad = pkg / "m.py"
    bad.write_text("def f():\n    from hil.cli import main\nfrom ..view import plot\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    found = imported_modules(bad)
    assert (2, "hil.cli") in found and (3, "hil.view") in found


def test_the_firmware_clock_is_the_can_library_default():
    assert TICK_HZ == DEFAULT_TICK_HZ


MODULE_LINES = 700
"""No product module over this many lines (issue: "a house the next engineer can live in")."""


def test_no_product_module_is_over_700_lines():
    sizes = {str(p.relative_to(ROOT)): len(p.read_text(encoding="utf-8").splitlines())
             for pkg in ("firmware_model", "can_bus", "hil") for p in (ROOT / pkg).rglob("*.py")}
    assert {m: n for m, n in sizes.items() if n > MODULE_LINES} == {}
