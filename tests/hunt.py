"""scripts/sleep_hunt.py as a module, for the tests that run its random worlds (a script, not a
package module: loaded by path)."""
from __future__ import annotations

import importlib.util

from paths import ROOT


def sleep_hunt():
    path = ROOT / "scripts" / "sleep_hunt.py"
    spec = importlib.util.spec_from_file_location("sleep_hunt", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
