"""What every fuzz target shares: atheris when it is installed, and instrumentation of the
project's code when a target runs as the fuzzer's main program (not when the tests import it)."""
from __future__ import annotations

import contextlib

try:
    import atheris
except ImportError:  # pragma: no cover - depends on the environment
    atheris = None


def instrumented(main: bool):
    """Context manager around a target's imports of firmware_model."""
    if atheris is not None and main:
        return atheris.instrument_imports(include=["firmware_model"])
    return contextlib.nullcontext()
