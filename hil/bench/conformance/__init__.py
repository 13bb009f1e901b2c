"""The conformance kit (``rprs conformance``): see :mod:`hil.bench.conformance.tester`."""
from __future__ import annotations

from .tester import (BYTE, INVITE_EVERY, MISS_LIMIT, MS, POLL_SEND, POLL_WAIT, QUIET_GAP, TMAX,
                     TSLOT, TTRANS, TWIN, Check, ConformanceError, Heard, Report, SerialLink,
                     Tester, TesterLink, _forger, _succ)

__all__ = ["BYTE", "INVITE_EVERY", "MISS_LIMIT", "MS", "POLL_SEND", "POLL_WAIT", "QUIET_GAP",
           "TMAX", "TSLOT", "TTRANS", "TWIN", "Check", "ConformanceError", "Heard", "Report",
           "SerialLink", "Tester", "TesterLink", "_forger", "_succ"]
