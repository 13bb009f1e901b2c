"""``rprs wireshark``: the radio protocol's Wireshark dissector (hil/wireshark/rprs.lua)."""
from __future__ import annotations

import argparse
import os
import shutil
from pathlib import Path

from .common import UserError


def personal_plugins_dir() -> Path:
    """Wireshark's personal Lua plugins folder: on Linux and macOS
    ``$XDG_CONFIG_HOME/wireshark/plugins`` (``~/.config/wireshark/plugins``) when that
    folder exists, else ``~/.local/lib/wireshark/plugins``; on Windows
    ``%APPDATA%\\Wireshark\\plugins``."""
    if os.name == "nt":                    # Windows: %APPDATA%\Wireshark\plugins
        return Path(os.environ.get("APPDATA") or Path.home() / "AppData" / "Roaming") \
            / "Wireshark" / "plugins"
    config = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
    if (config / "wireshark" / "plugins").is_dir():
        return config / "wireshark" / "plugins"
    return Path.home() / ".local" / "lib" / "wireshark" / "plugins"


def cmd_wireshark(a: argparse.Namespace) -> int:
    from ..wireshark import plugin_path
    src = plugin_path()
    if a.dir and not a.install:
        raise UserError("--dir names where --install copies the dissector: give --install too")
    if a.install:
        dest_dir = Path(a.dir) if a.dir else personal_plugins_dir()
        try:
            dest_dir.mkdir(parents=True, exist_ok=True)
            dest = dest_dir / src.name
            shutil.copyfile(src, dest)
        except OSError as exc:
            raise UserError(f"cannot install the dissector in {dest_dir}: "
                            f"{exc.strerror or exc}") from None
        print(f"installed {dest}: restart Wireshark (or Analyze > Reload Lua Plugins)")
        return 0
    print(src)
    return 0


def add(sub) -> None:
    w = sub.add_parser("wireshark", help="the radio protocol's Wireshark dissector: where it "
                       "is, or install it")
    g = w.add_mutually_exclusive_group()
    g.add_argument("--path", action="store_true", help="print the dissector's path (the "
                   "default), e.g. for tshark -X lua_script:PATH")
    g.add_argument("--install", action="store_true", help="copy it to Wireshark's personal "
                   "plugins folder")
    w.add_argument("--dir", metavar="DIR", help="with --install: this folder instead")
    w.set_defaults(func=cmd_wireshark)
