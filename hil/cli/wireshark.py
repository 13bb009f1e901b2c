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
    for opt in ("dir", "dbc"):
        if getattr(a, opt) and not a.install:
            raise UserError(f"--{opt} is for --install (where the dissector goes, and whose DBC "
                            f"it decodes the CAN payloads with): give --install too")
    if a.install:
        text = None
        if a.dbc:
            from ..wireshark.dbc_table import load_dbc, with_table
            try:
                text = with_table(src.read_text(encoding="utf-8"), load_dbc(Path(a.dbc)),
                                  a.dbc)
            except ValueError as exc:
                raise UserError(f"--dbc: {exc}") from None
        dest_dir = Path(a.dir) if a.dir else personal_plugins_dir()
        try:
            dest_dir.mkdir(parents=True, exist_ok=True)
            dest = dest_dir / src.name
            if text is None:
                shutil.copyfile(src, dest)
            else:
                dest.write_text(text, encoding="utf-8")
        except OSError as exc:
            raise UserError(f"cannot install the dissector in {dest_dir}: "
                            f"{exc.strerror or exc}") from None
        print(f"installed {dest}" + (f" (CAN payloads decoded with {a.dbc})" if a.dbc else "")
              + ": restart Wireshark (or Analyze > Reload Lua Plugins)")
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
    w.add_argument("--dbc", metavar="FILE", help="with --install: decode the CAN payloads with "
                   "this DBC (your own submodules') instead of can_bus/rprs.dbc")
    w.set_defaults(func=cmd_wireshark)
