"""``rprs wireshark``: the radio protocol's Wireshark dissector (hil/wireshark/rprs.lua)."""
from __future__ import annotations

import argparse
import os
import shutil
from pathlib import Path

from .common import UserError, file_name


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


def personal_extcap_dir() -> Path:
    """Wireshark's personal extcap folder: ``$XDG_CONFIG_HOME/wireshark/extcap`` before
    Wireshark 4.2 (the one ``tshark``/``wireshark -v`` on the PATH says), else
    ``~/.local/lib/wireshark/extcap``."""
    import re
    import subprocess
    for tool in ("tshark", "wireshark"):
        exe = shutil.which(tool)
        if exe is None:
            continue
        try:
            out = subprocess.run([exe, "-v"], capture_output=True, text=True, timeout=20).stdout
        except (OSError, subprocess.SubprocessError):
            continue
        m = re.search(r"\b(\d+)\.(\d+)\.\d+", out)
        if m and (int(m.group(1)), int(m.group(2))) < (4, 2):
            config = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
            return config / "wireshark" / "extcap"
        break
    return Path.home() / ".local" / "lib" / "wireshark" / "extcap"


def install_extcap(where: str | None) -> int:
    """``--install-extcap``: a launcher of hil.cli.extcap, run by this Python, in the
    personal extcap folder (or ``where``)."""
    import shlex
    import sys
    if os.name == "nt":
        raise UserError("the extcap launcher is a POSIX shell script; on Windows capture with "
                        "rprs capture --radio PORT --pcap - | wireshark -k -i -")
    dest_dir = Path(where) if where else personal_extcap_dir()
    dest = dest_dir / "rprs-radio"
    script = (f"#!/bin/sh\n# RPRS radio capture for Wireshark (rprs wireshark --install-extcap)\n"
              f"exec {shlex.quote(sys.executable)} -m hil.cli.extcap \"$@\"\n")
    _a_directory(dest_dir)
    replaced = dest.exists()
    try:
        dest_dir.mkdir(parents=True, exist_ok=True)
        dest.write_text(script, encoding="utf-8")
        dest.chmod(0o755)
    except OSError as exc:
        raise UserError(f"cannot install the extcap launcher in {dest_dir}: "
                        f"{exc.strerror or exc}") from None
    print(f"{'replaced' if replaced else 'installed'} {dest}: Wireshark lists the interface "
          f"rprs-radio (restart it); give it the radio's port in its options")
    return 0


def _a_directory(d: Path) -> None:
    """UserError if ``d``, or a folder it would be made in, is a file (mkdir said "File
    exists")."""
    for p in (d, *d.parents):
        if p.exists():
            if not p.is_dir():
                raise UserError(f"cannot install in {d}: {p} is a file, not a directory")
            return


def cmd_wireshark(a: argparse.Namespace) -> int:
    from ..wireshark import plugin_path
    src = plugin_path()
    if a.install_extcap:
        if a.dbc:
            raise UserError("--dbc is for --install (the dissector), not --install-extcap")
        return install_extcap(a.dir)
    for opt in ("dir", "dbc"):
        if getattr(a, opt) and not a.install:
            raise UserError(
                "--dir is for --install or --install-extcap (where the dissector or the "
                "capture's launcher goes): give one of them too" if opt == "dir" else
                "--dbc is for --install (whose DBC the dissector decodes the CAN payloads "
                "with): give --install too")
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
        _a_directory(dest_dir)
        replaced = (dest_dir / src.name).exists()
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
        print(f"{'replaced' if replaced else 'installed'} {dest}"
              + (f" (CAN payloads decoded with {a.dbc})" if a.dbc else "")
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
    g.add_argument("--install-extcap", action="store_true", help="put a launcher of the live "
                   "radio capture (interface rprs-radio) in Wireshark's personal extcap folder")
    w.add_argument("--dir", type=file_name, metavar="DIR",
                   help="with --install or --install-extcap: this "
                   "folder instead")
    w.add_argument("--dbc", metavar="FILE", help="with --install: decode the CAN payloads with "
                   "this DBC (your own submodules') instead of can_bus/rprs.dbc")
    w.set_defaults(func=cmd_wireshark)
