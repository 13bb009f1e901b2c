"""The CAN part of the Wireshark dissector, generated from ``can_bus/rprs.dbc``.

Wireshark cannot read a DBC file. ``rprs.lua`` therefore carries a Lua table of every message
of the DBC (identifier, name, sender, length, signals with byte offset, size, sign, scale,
offset, unit and value names) between two marker lines, and decodes the payload of the CAN
frames in a capture from it (Wireshark's ``can.id`` dissector table). The table is generated
here; ``tests/hil/test_pcap.py`` checks that the file's table is the one the DBC gives, so a DBC
change without regenerating fails CI:

    python -m hil.wireshark.dbc_table          # rewrites the table in rprs.lua
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from can_bus import dbc
from hil.wireshark import plugin_path

BEGIN = "-- BEGIN DBC TABLE (generated from can_bus/rprs.dbc by python -m hil.wireshark.dbc_table)"
END = "-- END DBC TABLE"


def _lua_string(text: str) -> str:
    if not text.isascii():
        raise ValueError(f"{text!r}: the Lua table takes ASCII text only")
    return json.dumps(text)        # "..." with \" and \\ escapes: the same in Lua


def _number(x: float) -> str:
    return repr(int(x)) if float(x).is_integer() else repr(float(x))


def load_dbc(path: Path) -> Any:
    """A user's DBC file (``rprs wireshark --install --dbc FILE``), loaded strictly by
    cantools; a file that cannot be read or is not a DBC is a ValueError saying why."""
    import cantools
    try:
        db = cantools.database.load_file(str(path), database_format="dbc", strict=True)
    except OSError as exc:
        raise ValueError(f"cannot read {path}: {exc.strerror or exc}") from None
    except Exception as exc:       # cantools' parse and strict-check errors have no common base
        raise ValueError(f"{path} is not a DBC cantools can load: {exc}") from None
    if not isinstance(db, cantools.database.can.Database) or not db.messages:
        raise ValueError(f"{path} defines no CAN message")
    return db


def lua_table(db: Any = None, origin: str | None = None) -> str:
    """The table's Lua source, marker lines included: of can_bus/rprs.dbc, or of the cantools
    database ``db`` (read from ``origin``, named in a comment)."""
    lines = [BEGIN]
    if origin is not None:
        lines.append(f"-- this copy's table: from {origin}")
    lines.append("local dbc_messages = {")
    for m in sorted((db or dbc.load()).messages, key=lambda m: m.frame_id):
        sigs = []
        for s in m.signals:
            if s.byte_order != "little_endian" or s.start % 8 or s.length not in (8, 16, 32) \
                    or s.is_float or s.is_multiplexer or s.multiplexer_ids:
                raise ValueError(f"{m.name}.{s.name}: the dissector decodes byte-aligned "
                                 f"little-endian integer signals of 8, 16 or 32 bits only")
            choices = ""
            if s.choices:
                items = ", ".join(f"[{int(k)}] = {_lua_string(str(v))}"
                                  for k, v in sorted(s.choices.items()))
                choices = f", choices = {{ {items} }}"
            sigs.append(f"      {{ name = {_lua_string(s.name)}, byte = {s.start // 8}, "
                        f"size = {s.length // 8}, signed = {'true' if s.is_signed else 'false'}, "
                        f"scale = {_number(s.scale)}, offset = {_number(s.offset)}, "
                        f"unit = {_lua_string(s.unit or '')}{choices} }},")
        lines.append(f"  [0x{m.frame_id:03x}] = {{ name = {_lua_string(m.name)}, "
                     f"sender = {_lua_string(','.join(m.senders))}, dlc = {m.length}, "
                     "signals = {")
        lines += sigs
        lines.append("  } },")
    lines += ["}", END]
    return "\n".join(lines) + "\n"


def section(text: str) -> str:
    """The table as it stands in a plugin's ``text`` (marker lines included)."""
    i, j = text.find(BEGIN), text.find(END)
    if i < 0 or j < i:
        raise ValueError("the plugin has no DBC table between the marker lines")
    return text[i:j + len(END)] + "\n"


def with_table(text: str, db: Any, origin: str) -> str:
    """The plugin ``text`` with its table made from the cantools database ``db``."""
    return text.replace(section(text), lua_table(db, origin))


def write(path: Path | None = None) -> bool:
    """Rewrite the table in the plugin at ``path``; True if it changed."""
    path = Path(path) if path is not None else plugin_path()
    text = path.read_text(encoding="utf-8")
    new = text.replace(section(text), lua_table())
    if new == text:
        return False
    path.write_text(new, encoding="utf-8")
    return True


def main(argv: list[str] | None = None) -> int:
    """``python -m hil.wireshark.dbc_table [PLUGIN]``: rewrite the plugin's DBC table from
    can_bus/rprs.dbc. A missing or unreadable plugin, or one without the marker lines, is one
    line on stderr and exit status 2."""
    import argparse
    p = argparse.ArgumentParser(prog="python -m hil.wireshark.dbc_table",
                                description="Rewrite the Wireshark plugin's CAN signal table "
                                "from can_bus/rprs.dbc.")
    p.add_argument("plugin", nargs="?", type=Path, default=None,
                   help=f"the plugin to rewrite (default: {plugin_path()})")
    args = p.parse_args(argv)
    try:
        changed = write(args.plugin)
    except (OSError, ValueError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
        print(f"{p.prog}: error: {args.plugin or plugin_path()}: {why}", file=sys.stderr)
        return 2
    print("rewrote the DBC table" if changed else "the DBC table was up to date")
    return 0


if __name__ == "__main__":
    sys.exit(main())
