"""Helpers for tests that drive a textual app with its pilot (``app.run_test()``)."""
from __future__ import annotations


async def stopped_within(app, pilot, seconds: float = 5.0) -> bool:
    """Whether ``app`` stops running within ``seconds`` (wall), checked every 0.1 s."""
    for _ in range(int(seconds * 10)):
        await pilot.pause(0.1)
        if not app.is_running:
            return True
    return not app.is_running
