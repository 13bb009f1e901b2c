"""One property, two budgets: a few examples in the fast tier (the README's test command), the
full budget in the slow tier (``pytest -m slow``, CI's second step)."""
from __future__ import annotations

from typing import Callable

import pytest
from hypothesis import settings


def quick_and_thorough(make: Callable[[settings], object], quick: settings,
                       thorough: settings) -> tuple[object, object]:
    """``make(budget)`` builds the test (``budget(given(...)(body))``); returns it built with
    ``quick`` for the fast tier and with ``thorough``, marked slow, for the slow tier. Bind
    both to module names: the second as ``<name>_thoroughly``."""
    return make(quick), pytest.mark.slow(make(thorough))
