"""Coverage-guided fuzz target: the Content parser (firmware_model.radio.content).

Run:  .venv/bin/python fuzz/fuzz_content.py -atheris_runs=100000 [CORPUS_DIR ...]

The first input byte chooses how the rest becomes Content: odd -> the bytes as they are (any
byte string, printable or not); even -> a token sequence decoded with
atheris.FuzzedDataProvider (command names from COMMANDS and near misses, '(' ')' ',' '-' '.',
digit runs of every length, any byte), because coverage feedback alone cannot guess the names
(they are looked up in a dict, not compared). Properties (:func:`check_content`):

1. ``parse_content(data)`` raises nothing but ContentError, for bytes and for the same input as
   ``str`` (latin-1 decoded, so non-ASCII text is exercised too);
2. a ContentError has ``offset`` inside the data (0..len) and ``field`` 'command' or 'params';
3. when it parses, ``format_content(commands)`` parses back to the same commands, and formatting
   is a fixed point from then on (format -> parse -> format gives the same bytes);
4. the str and bytes paths agree.
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _harness import atheris, instrumented  # noqa: E402

with instrumented(__name__ == "__main__"):
    from firmware_model.radio.content import COMMANDS, format_content, parse_content
    from firmware_model.radio.errors import ContentError

__all__ = ["TOKENS", "draw_tokens", "check_content", "TestOneInput", "main"]

TOKENS: tuple[bytes, ...] = tuple(n.encode() for n in COMMANDS) + (
    b"(", b")", b",", b"-", b".", b"0", b"1", b"9", b"00", b"127", b"999", b"65535",
    b"movexx", b"move", b"MOVEX", b"_", b"crc", b"1.5", b"-0", b"0.001", b"0.0001",
    b"123456789012", b"1234567890123", b" ", b"\x00", b"\x7f", b"\xff", b"+1", b"1e3",
)
"""What Content is made of: names, punctuation, numbers of interesting sizes, bad bytes."""


def draw_tokens(src, max_tokens: int = 40) -> bytes:
    """Content built from :data:`TOKENS` and single bytes, ``src`` as in fuzz_deframer."""
    out = []
    for _ in range(max_tokens):
        if not src.more():
            break
        if src.int(0, 9):
            out.append(src.pick(TOKENS))
        else:
            out.append(bytes([src.int(0, 255)]))
    return b"".join(out)


def _parse(data):
    """('ok', commands) or ('err', ContentError); anything else propagates (a finding)."""
    try:
        return "ok", parse_content(data)
    except ContentError as exc:
        return "err", exc


def check_content(data: bytes):
    """Assert the Content properties (module docstring); returns the commands or None."""
    kind, res = _parse(data)
    if kind == "err":
        assert res.field in ("command", "params"), res
        assert res.offset is not None and 0 <= res.offset <= len(data), res
    text_kind, text_res = _parse(data.decode("latin-1"))
    if data.isascii():
        assert (text_kind, text_res) == (kind, res), (data, res, text_res)
    else:
        assert text_kind == "err"
    if kind == "err":
        return None
    wire = format_content(res)
    again = parse_content(wire)
    assert again == res, (data, res, wire, again)
    assert format_content(again) == wire
    assert len(wire) <= len(data) or not data  # normalising never makes Content longer
    return res


class _Fdp:
    def __init__(self, fdp) -> None:
        self.fdp = fdp

    def int(self, lo: int, hi: int) -> int:
        return self.fdp.ConsumeIntInRange(lo, hi)

    def pick(self, seq):
        return self.fdp.PickValueInList(list(seq))

    def more(self) -> bool:
        return self.fdp.remaining_bytes() > 0


def TestOneInput(data: bytes) -> None:
    if not data or data[0] & 1:
        check_content(data[1:])
    else:
        check_content(draw_tokens(_Fdp(atheris.FuzzedDataProvider(data[1:]))))


def main(argv: list[str] | None = None) -> None:
    if atheris is None:
        sys.exit("atheris is not installed: .venv/bin/pip install atheris")
    atheris.Setup(sys.argv if argv is None else argv, TestOneInput)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
