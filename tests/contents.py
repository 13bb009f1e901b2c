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


def frames(max_content: int):
    """A hypothesis strategy for frames with any field in its wire range (Destination 0-9,
    Source 0-6, Number 0-99, Type 0-9) and printable Content of at most ``max_content`` bytes
    (docs/protocol.md §3.1)."""
    from hypothesis import strategies as st

    from firmware_model.radio.frame import Frame
    printable = st.lists(st.integers(0x20, 0x7E), max_size=max_content).map(bytes)
    return st.builds(Frame, dst=st.integers(0, 9), src=st.integers(0, 6),
                     num=st.integers(0, 99), type=st.integers(0, 9), content=printable)
