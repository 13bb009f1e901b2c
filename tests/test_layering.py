"""The import rules of docs/architecture.md, checked on the source: ``can_bus`` is a CAN library
that stands alone (it imports neither ``firmware_model`` nor ``hil``), ``firmware_model`` never
imports ``hil``, and the rooms of ``hil`` import only downwards: ``sim`` nothing of the others,
``bench`` only ``sim``, ``view`` ``sim`` and ``bench``, ``cli`` anything. Every import
statement counts, including ones inside functions; relative imports are resolved."""
from __future__ import annotations

import ast
import os
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


TEST_ROOMS_BESIDE_PACKAGES = ("docs", "benchmarks", "acceptance", "data")
"""Folders of ``tests/`` that mirror no package: the docs' checks, the benchmark scripts'
tests, the acceptance tests (which run against the model or a flashed board) and test data."""

PROJECT_WIDE_TESTS = {"test_layering.py", "test_tiers.py"}
"""The tests about the project as a whole (its import rules, its test tiers), at the top of
``tests/`` beside the helpers every folder shares (``processes.py``, ``paths.py``, ...)."""


def test_the_tests_mirror_the_packages():
    """A test module lives in the folder of the package it tests (``tests/firmware_model/radio/``
    for ``firmware_model/radio/``), or in one of the rooms beside them; helpers shared by
    tests stay at the top of ``tests/``, and no two test modules share a name (pytest imports
    them by name)."""
    tests = ROOT / "tests"
    stray, names = [], {}
    for p in tests.rglob("test_*.py"):
        rel = p.relative_to(tests)
        names.setdefault(p.name, []).append(rel.as_posix())
        if len(rel.parts) == 1:
            if p.name not in PROJECT_WIDE_TESTS:
                stray.append(rel.as_posix())
        elif rel.parts[0] not in TEST_ROOMS_BESIDE_PACKAGES and \
                not (ROOT / rel.parent).is_dir():
            stray.append(rel.as_posix())
    assert stray == [], f"test modules outside a package's mirror or a room: {stray}"
    assert {n: ps for n, ps in names.items() if len(ps) > 1} == {}
    helpers = [p.relative_to(tests).as_posix() for p in tests.rglob("*.py")
               if not p.name.startswith("test_") and p.name != "conftest.py"
               and p.parent != tests and "acceptance" not in p.parts]
    assert helpers == [], f"shared helpers belong at the top of tests/: {helpers}"


def test_the_packages_tests_import_are_the_real_ones():
    """tests/hil/, tests/can_bus/ and tests/firmware_model/ sit under tests/, which pytest puts
    on sys.path; pyproject's ``pythonpath`` puts the checkout there too, so that the packages
    imported are the real ones (with their ``__init__.py``), never those folders as namespace
    packages. A fresh interpreter with tests/ first on its path shows it."""
    import subprocess

    import can_bus
    import firmware_model
    import hil
    assert str(ROOT) in sys.path
    assert [m.__file__ for m in (can_bus, firmware_model, hil)] == \
        [str(ROOT / p / "__init__.py") for p in ("can_bus", "firmware_model", "hil")]
    code = ("import can_bus, firmware_model, hil; "
            "print(can_bus.__file__, firmware_model.__file__, hil.__file__)")
    env = {"PYTHONPATH": os.pathsep.join([str(ROOT / "tests"), str(ROOT)])}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         cwd=ROOT / "tests", timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [str(ROOT / p / "__init__.py")
                                  for p in ("can_bus", "firmware_model", "hil")], out.stdout
