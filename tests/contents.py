"""Content of a chosen length, for tests of the longest frames (docs/protocol.md clause 16)."""
from __future__ import annotations

from firmware_model.radio.content import cmd, format_content


def content_of(size: int) -> list:
    """``movex`` commands whose Content is exactly ``size`` bytes (``size`` >= 8)."""
    cmds: list = []
    while size - len(format_content(cmds)) >= 16 + 8:
        cmds.append(cmd("movex", 123456789))                # 16 bytes each
    rest = size - len(format_content(cmds))
    if rest > 16:
        cmds.append(cmd("movex", int("1" * (rest - 8 - 7))))
        rest = size - len(format_content(cmds))
    cmds.append(cmd("movex", int("1" * (rest - 7))))
    assert len(format_content(cmds)) == size
    return cmds
