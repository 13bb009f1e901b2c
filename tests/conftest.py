"""Shared pytest configuration and fixtures."""
from __future__ import annotations

import os
import uuid

import pytest


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "vcan: needs a SocketCAN vcan0 interface (run them for real with scripts/vcan-vm.sh)",
    )


@pytest.fixture(params=["virtual", pytest.param("socketcan", marks=pytest.mark.vcan)])
def can_channel(request) -> str:
    """A python-can ``INTERFACE:CHANNEL``: python-can's virtual bus everywhere, and SocketCAN
    vcan0 where the kernel has it (skipped with the reason elsewhere; under RPRS_VCAN=1, as in
    scripts/vcan-vm.sh, a missing vcan0 fails instead)."""
    if request.param == "virtual":
        return f"virtual:rprs-{uuid.uuid4().hex[:8]}"
    from can_bus.bridge import socketcan_missing
    channel = os.environ.get("RPRS_VCAN_CHANNEL", "vcan0")
    why = socketcan_missing(channel)
    if why:
        if os.environ.get("RPRS_VCAN") == "1":
            pytest.fail(f"RPRS_VCAN=1 but {why}")
        pytest.skip(f"{why}; run scripts/vcan-vm.sh for real SocketCAN")
    return f"socketcan:{channel}"
