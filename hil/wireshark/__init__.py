"""The Wireshark dissector of the RPRS radio protocol (``rprs.lua``), shipped in the package.

``plugin_path()`` is where it is; ``rprs wireshark --install`` copies it to the personal
plugins folder, ``rprs wireshark --path`` prints it (for ``tshark -X lua_script:PATH``).
"""
from __future__ import annotations

from pathlib import Path

PLUGIN = "rprs.lua"


def plugin_path() -> Path:
    """The dissector file in this installation."""
    return Path(__file__).with_name(PLUGIN)
