"""Shared pytest configuration."""


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "vcan: needs a SocketCAN vcan0 interface (run them for real with scripts/vcan-vm.sh)",
    )
