"""The father pair shares ID 0's Numbers (docs/protocol.md clause 50): a PC that hears the
other PC's message of Number N numbers its next message after N and after its own messages
still queued, which keep their Numbers."""
from __future__ import annotations

import pytest

from firmware_model.radio import mac as M
from firmware_model.radio.content import cmd
from firmware_model.radio.frame import Frame
from firmware_model.timing import CHILD_BYTE_TICKS as B


def _member_pc(pc: int) -> M.RotationalMac:
    """PC ``pc`` of a pair, active, invited into the ring {0, 1}, its first frame sent."""
    mac = M.RotationalMac(0, M.MacConfig(team=frozenset({0, 1}), paired=True, pc=pc))
    mac.power_on(0)
    t = 100 * B
    mac.on_frame(Frame(7, 1, 0, 3, b"poll(0,2)"), t - 23 * B, t, t)   # invited: ring {0, 1}
    while mac.phase != M.SEND:     # (PC2 watches its first turn: clause 50) -> SWITCH -> SEND
        mac.on_timer(mac.deadline)
    mac.on_tx_done(mac.turn_start + mac.cfg.ttrans + 20 * B)
    return mac


@pytest.mark.parametrize("pc", [1, 2])
def test_a_pc_numbers_past_its_queued_messages_after_the_other_pcs(pc):
    """PC1 stays active when it hears PC2's message (PC2 will yield); PC2 stands by. Either
    way its message 01 fails (the other PC's 01 took the Number) and its queued 02 keeps
    02: numbered 02 after the other's 01, the next message repeated it, and robot 1, having
    had the first 02, would take the second for a duplicate, acknowledged, never delivered."""
    mac = _member_pc(pc)
    t = mac.turn_start + 100 * B
    first = mac.submit(1, [cmd("joint", 1, 10)], t)
    queued = mac.submit(1, [cmd("joint", 2, 10)], t)
    assert (first.num, queued.num) == (1, 2)
    out = list(mac.on_frame(Frame(1, 0, 1, 2, b"joint(1,5)"), t + 10 * B, t + 40 * B,
                            t + 40 * B))
    assert first.state == "failed" and "the other PC sent its own message 01" in first.reason
    assert queued in mac.outbox and queued.num == 2
    assert mac.standby == (pc == 2), out
    if mac.standby:                  # a standby takes no order until it takes over
        mac.standby = False
    later = mac.submit(1, [cmd("joint", 3, 10)], t + 50 * B)
    assert later.num == 3
