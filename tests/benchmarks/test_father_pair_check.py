"""benchmarks/father_pair.py's check of the father's messages: which PC's frame delivered each.
A delivery is the frame's of its Number whose End is nearest: at that End's tick on the ideal
CPU, a little before it on the CPU model (the End byte's handler runs at its RDRF, before the
stop bit ends). Matched by equal ticks only, every delivery on the CPU model looked unsent."""
from __future__ import annotations

import importlib.util

import pytest

from paths import ROOT

_spec = importlib.util.spec_from_file_location("father_pair",
                                               ROOT / "benchmarks" / "father_pair.py")
father_pair = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(father_pair)


def _events(deliver_at: int, frame_pc: int, told_pc: int) -> list[dict]:
    """A frame of Number 5 from ID 0 (PC ``frame_pc``) ending at 1,000,000, another of Number 5
    a turn later, robot 1's delivery at ``deliver_at``, and PC ``told_pc`` told delivered."""
    pc = {} if frame_pc == 1 else {"pc": 2}
    told = {} if told_pc == 1 else {"pc": 2}
    return sorted([
        {"t": 1_000_000, "ev": "frame", "src": 0, "num": 5, **pc},
        {"t": deliver_at, "ev": "deliver", "src": 0, "num": 5, "to": 1},
        {"t": 1_700_000, "ev": "frame", "src": 0, "num": 5, **pc},
        {"t": 1_800_000, "ev": "delivered", "src": 0, "num": 5, "dst": 1, **told}],
        key=lambda e: e["t"])


@pytest.mark.parametrize("deliver_at", [1_000_000, 986_000])   # ideal CPU, CPU model
def test_a_delivery_is_the_nearest_frames_of_its_number(deliver_at):
    assert father_pair._fathers(_events(deliver_at, 1, 1)) == {
        "father_acknowledged": 1, "father_unsent": 0}


@pytest.mark.parametrize("deliver_at", [1_000_000, 986_000])
def test_a_pc_told_delivered_by_the_other_pcs_frame_is_counted(deliver_at):
    assert father_pair._fathers(_events(deliver_at, 2, 1)) == {
        "father_acknowledged": 1, "father_unsent": 1}
