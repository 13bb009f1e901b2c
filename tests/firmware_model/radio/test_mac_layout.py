"""The rotational MAC's layout (issue 44; docs/architecture.md): mac.py and the mac_*.py
modules beside it, none over 700 lines, and every public name mac.py offered when it was one
module still importable from it (``from firmware_model.radio.mac import MacConfig, Deliver``
in modules, tests, scripts and whatever else uses the package)."""
from __future__ import annotations

from pathlib import Path

from firmware_model.radio import mac as M

OFFERED = (
    "BEHIND_WINDOW", "BadChecksum", "BadContent", "CHILD_BYTE_TICKS", "DEADLINE_HANDLERS",
    "Deliver", "Disable", "Duplicate", "DuplicateId", "FAILING_SLOT_LIMIT", "ForeignRing",
    "HOLD", "Join", "LET_PASS_MAX", "LISTEN", "MEMBER", "MISS_LIMIT", "MacConfig", "Message",
    "Miss", "ModeChange", "NumberBehind", "Outcome", "PC2_CHECK_EVERY", "PC_BYTE_TICKS",
    "PROFILES", "QUIET", "QueueFull", "Refused", "RotationalMac", "SEND", "SWITCH", "StandingBy",
    "SubmitError", "TAKEOVER_TOLERANCE", "TMAX_TICKS", "TTRANS_TICKS", "TWIN_FRAMES", "TX_OFF",
    "TX_ON", "Transmit", "TxEnable", "UNACKNOWLEDGED", "WAIT", "WATCH", "WINDOW",
    "check_submission", "_layers",
)
"""The public names of mac.py as one module (and ``_layers``, which peer_macs.py imports)."""


def test_no_mac_module_is_over_700_lines():
    sizes = {p.name: len(p.read_text().splitlines())
             for p in Path(M.__file__).parent.glob("mac*.py")}
    assert len(sizes) > 1
    assert {n: s for n, s in sizes.items() if s > 700} == {}


def test_every_name_mac_offered_is_still_importable_from_it():
    assert [n for n in OFFERED if not hasattr(M, n)] == []
    assert [n for n in M.__all__ if not hasattr(M, n)] == []

