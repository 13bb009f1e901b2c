"""``rprs encode`` and ``rprs decode``: frames to hex and back, from the command line or a
stream."""
from __future__ import annotations

import argparse
import binascii
import io
import json
import re
import sys
from typing import Iterable, cast

from firmware_model.radio import auth, integrity
from firmware_model.radio.content import AUTH_TAIL, parse_content
from firmware_model.radio.deframer import Deframer, FrameFailed, FrameReceived, Garbage
from firmware_model.radio.errors import WireError
from firmware_model.radio.frame import MAX_CONTENT, Frame
from firmware_model.timing import PC_BYTE_TICKS, max_content_bytes

from .common import UserError, auth_key, digit

def cmd_encode(a: argparse.Namespace) -> int:
    content = a.content.encode("ascii", "strict") if a.content.isascii() else None
    if content is None:
        raise UserError("Content must be ASCII text such as 'movex(10)'")
    if len(content) > MAX_CONTENT:
        # docs/protocol.md clause 11: Length is at most 562; a longer Content is refused,
        # never cut (clause 14). `rprs inject --hex` writes any bytes, an invalid frame too.
        raise UserError(f"Content is {len(content)} bytes, more than a frame carries "
                        f"({MAX_CONTENT}, docs/protocol.md clause 11)")
    if a.fresh is not None and a.auth_key is None:
        raise UserError("--fresh goes with --auth-key (the freshness value of a signed frame)")
    try:
        commands = parse_content(content)
        if (a.checksum or a.auth_key is not None) and CRC_TAIL.search(content):
            raise UserError("the Content already ends with crc(...); "
                            f"{'--checksum' if a.checksum else '--auth-key'} seals it itself: "
                            "give the Content without it (or leave the option out to send it "
                            "as it is)")
        crcs = [i for i, c in enumerate(commands) if c.name == "crc"]
        if crcs and crcs[-1] != len(commands) - 1 or len(crcs) > 1:
            print("rprs encode: note: crc(...) comes once, last, in a Content (docs/protocol.md "
                  "clause 20): a receiver with the checksum extension takes this frame as "
                  "failed", file=sys.stderr)
        # a crc's number is written in five digits, zero padded (clause 20)
        written = "".join(f"crc({c.args[0]:05d})" if c.name == "crc" else c.text()
                          for c in commands)
        if written != content.decode("ascii"):
            print(f"rprs encode: note: a sender writes numbers as {written!r} (docs/protocol.md "
                  f"clauses 17, 20); receivers must still take these", file=sys.stderr)
        if a.auth_key is not None:
            # the authenticated profile's last command, sealed as a station does (clause 52)
            frame = auth.seal(a.auth_key, a.dst, a.src, a.num, a.type, content, a.fresh or 0)
        elif a.checksum:
            frame = integrity.seal(a.dst, a.src, a.num, a.type, content)      # clause 20
        else:
            frame = Frame(dst=a.dst, src=a.src, num=a.num, type=a.type, content=content)
        if len(frame.content) > MAX_CONTENT:
            # Length counts the crc() or auth() the seal adds (clauses 11, 20, 52): refused,
            # never cut (clause 14)
            raise UserError(f"Content is {len(content)} bytes, {len(frame.content)} with the "
                            f"{'auth()' if a.auth_key is not None else 'crc()'} it ends with: "
                            f"more than a frame carries ({MAX_CONTENT}, docs/protocol.md "
                            f"clause 11)")
        pc_max = max_content_bytes(PC_BYTE_TICKS)
        if a.dst in (8, 9) or a.type >= 7 or a.dst == a.src or (
                a.src == 0 and len(frame.content) > pc_max):
            what = ("Destination '8' and '9' are reserved" if a.dst in (8, 9) else
                    f"Type '{a.type}' is reserved" if a.type >= 7 else
                    "a station never sends to its own ID" if a.dst == a.src else
                    f"a PC sends at most {pc_max} Content bytes, its crc() or auth() counted "
                    f"(its bytes are longer; clause 14)")
            print(f"rprs encode: note: {what}: no station sends this frame (docs/protocol.md "
                  f"§3); receivers must still take it", file=sys.stderr)
        data = frame.encode()
    except WireError as exc:
        raise UserError(str(exc)) from None
    print(data.hex(" ") if a.spaced else data.hex())
    return 0


def _frame_json(frame: Frame, key=None) -> dict:
    """A frame as JSON: its fields, its commands (an ``auth(...)`` or ``crc(...)`` that ends
    it reported apart, with whether it holds: ``tag_ok`` with the ring key, else null;
    ``crc_ok``), or why its Content is unreadable."""
    content = frame.content
    d = {"dst": frame.dst, "src": frame.src, "num": frame.num, "type": frame.type,
         "len": len(content), "content": content.decode("ascii")}
    if AUTH_TAIL.search(content):
        fresh, tag = content[-auth.AUTH_TEXT_LEN + 5:-1].decode("ascii").split(",")
        d["auth"] = {"fresh": fresh, "tag": tag, "tag_ok": None if key is None else
                     auth.check(key, frame) is not None}
        content = auth.strip(content)
    elif CRC_TAIL.search(content) and int(content[-6:-1]) <= CRC_MAX:
        # (a value past 16 bits is no checksum: left in, it makes the Content unreadable,
        # as the firmware finds it, clause 16)
        d["crc"] = int(content[-6:-1])
        d["crc_ok"] = integrity.check(frame)
        content = integrity.strip(content)
    try:
        d["commands"] = [[c.name, list(c.args)] for c in parse_content(content)]
    except WireError as exc:
        d["content_error"] = str(exc)
    return d


CRC_TAIL = re.compile(rb"crc\([0-9]{5}\)\Z")
"""``crc(NNNNN)`` ending a Content (the checksum extension, docs/protocol.md clause 20)."""

CRC_MAX = 65535
"""The largest ``crc(value)``: a CRC-16 (docs/protocol.md, clause 20; its parameter's bounds)."""


def _decode_bytes(chunks, out, key=None) -> tuple[int, int]:
    """Print what the bytes hold, a row each; returns (frames decoded, bytes read)."""
    d = Deframer()
    offset = 0
    frames = 0
    for data in chunks:
        for ev in d.feed(data, offset, 1):
            if isinstance(ev, FrameReceived):
                frames += 1
                out({"offset": ev.first, "frame": _frame_json(ev.frame, key)})
            elif isinstance(ev, Garbage):
                out({"offset": ev.first, "garbage": ev.count})
            elif isinstance(ev, FrameFailed):
                out({"offset": ev.first, "error": str(ev.error)})
        offset += len(data)
    cut = d.abort(offset)
    if cut is not None:
        out({"offset": cut.first, "error": f"truncated: {cut.error}"})
    for ev in d.flush():
        if isinstance(ev, Garbage):
            out({"offset": ev.first, "garbage": ev.count})
    return frames, offset


def _unhex(text: str) -> bytes:
    cleaned = "".join(text.split())
    try:
        return binascii.unhexlify(cleaned)
    except (binascii.Error, ValueError):
        raise UserError("input is not hexadecimal bytes (e.g. 0f0a05...)") from None


def cmd_decode(a: argparse.Namespace) -> int:
    def out(obj):
        print(json.dumps(obj), flush=False)
    if a.stream and a.hexdata:
        raise UserError("--stream reads stdin: give the frame as HEX or --stream, not both")
    if a.stream:
        if sys.stdin is None:
            raise UserError("standard input is closed: --stream reads the bytes from it")
        chunks: Iterable[bytes]
        if a.hex:
            chunks = (_unhex(line) for line in sys.stdin)
        else:
            # (a buffered reader: read1 hands over what has come, without waiting for more)
            src = cast(io.BufferedIOBase, sys.stdin.buffer)
            chunks = iter(lambda: src.read1(4096), b"")
        frames, size = _decode_bytes(chunks, out, a.auth_key)
    else:
        if not a.hexdata:
            raise UserError("give the frame as hex, or --stream to read stdin")
        frames, size = _decode_bytes([_unhex(" ".join(a.hexdata))], out, a.auth_key)
    sys.stdout.flush()
    if not frames:       # found nothing: status 1, as rprs bench link or cycle hearing no frame
        print(f"rprs decode: no frame in {size} bytes of input", file=sys.stderr)
        return 1
    print(f"{frames} frame(s) decoded", file=sys.stderr)
    return 0


def _freshness(text: str) -> int:
    """``--fresh``: 0 to ffffffff, decimal or ``0x`` hex."""
    try:
        v = int(text[2:], 16) if text.lower().startswith("0x") else int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"freshness value {text!r} is not a whole number "
                                         f"(decimal, or 0x and hex digits)") from None
    if not 0 <= v <= auth.FRESH_MAX:
        raise argparse.ArgumentTypeError(f"freshness value must be 0-0xffffffff, got {text}")
    return v


def add(sub) -> None:
    e = sub.add_parser("encode", help="print a frame as hex")
    e.add_argument("--src", type=digit(0, 6, "source"), required=True,
                   help="Source robot ID (0-6)")
    e.add_argument("--dst", type=digit(0, 9, "destination"), required=True,
                   help="Destination digit (0-6 a robot, 7 all)")
    e.add_argument("--num", type=digit(0, 99, "number"), default=0,
                   help="Number, 0-99 (default %(default)s)")
    e.add_argument("--type", type=digit(0, 9, "type"), default=2,
                   help="Type digit (default %(default)s, a message; docs/protocol.md §3)")
    e.add_argument("--spaced", action="store_true", help="space between bytes")
    seal = e.add_mutually_exclusive_group()
    seal.add_argument("--checksum", action="store_true",
                      help="end the Content with its crc(NNNNN) (docs/protocol.md clause 20)")
    seal.add_argument("--auth-key", type=auth_key, metavar="FILE", default=None,
                      help="sign the frame: end the Content with auth(fresh,tag) under this "
                      "ring key file (docs/protocol.md clause 52)")
    e.add_argument("--fresh", type=_freshness, default=None, metavar="N",
                   help="with --auth-key: the freshness value, decimal or 0x hex (default 0)")
    e.add_argument("content", help="Content text, e.g. 'movex(10)moveto(1.5,-2,0)'; without "
                   "the crc() or auth() that --checksum or --auth-key add")
    e.set_defaults(func=cmd_encode)
    c = sub.add_parser("decode", help="find frames in hex or in a byte stream",
                       description="Find frames in hex or in a byte stream: a JSON line on "
                       "stdout for each frame, run of garbage and broken frame. Exit status "
                       "1 when no frame is found.")
    c.add_argument("hexdata", nargs="*", metavar="HEX")
    c.add_argument("--stream", action="store_true", help="read bytes from stdin")
    c.add_argument("--hex", action="store_true", help="with --stream: stdin is hex text "
                   "(without --stream the HEX arguments are hex already)")
    c.add_argument("--auth-key", type=auth_key, metavar="FILE", default=None,
                   help="check each auth(fresh,tag) with this ring key file ('tag_ok'; "
                   "without it the tag is shown, not checked); crc() is always checked")
    c.set_defaults(func=cmd_decode)
