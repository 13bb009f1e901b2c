"""JSON Lines trace of a run: one event a line, schema in docs/trace.md.

The first line is the ``meta`` event; every later line has ``t`` (tick, non-decreasing) and
``ev``. Keys are written in a fixed order and numbers as integers, so the same seed gives a
byte-identical file.
"""
from __future__ import annotations

import errno
import gzip
import json
import os
import zlib
from typing import IO, Any, Iterator

TRACE_VERSION = 1


def open_partial(path: str) -> tuple[str, IO[str]]:
    """(``PATH.partial``, that file open for ASCII text): a writer renames it to ``path`` when
    complete. ``path`` naming a directory is refused here (OSError), before anything is
    written, rather than at the rename after the whole run."""
    if os.path.isdir(path):
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), path)
    tmp = f"{path}.partial"
    return tmp, open(tmp, "w", encoding="ascii", newline="\n")


class TraceWriter:
    """Writes events to ``path`` atomically: the file appears complete at ``close()`` or not at
    all (a run that fails leaves no partial trace behind)."""

    def __init__(self, path: str) -> None:
        self.path = path
        self._tmp, self._f = open_partial(path)
        self._dumps = json.JSONEncoder(separators=(",", ":"), ensure_ascii=True).encode
        self.count = 0

    def write(self, ev: dict[str, Any]) -> None:
        self._f.write(self._dumps(ev))
        self._f.write("\n")
        self.count += 1

    def close(self) -> None:
        self._f.close()
        os.replace(self._tmp, self.path)

    def discard(self) -> None:
        self._f.close()
        try:
            os.unlink(self._tmp)
        except FileNotFoundError:
            pass


class TraceError(ValueError):
    """A trace file that cannot be read: says which line and why."""


def read_trace(path: str) -> Iterator[dict[str, Any]]:
    """Yield the events of a trace file (plain or gzip-compressed, told apart by the gzip
    magic bytes), checking the meta line comes first. A file that is not a trace (an image,
    a README, a truncated gzip) raises ``TraceError`` naming the line."""
    try:
        raw = open(path, "rb")
    except OSError as exc:
        raise TraceError(f"cannot read trace {path}: {exc.strerror}") from None
    with raw:
        compressed = raw.peek(2)[:2] == b"\x1f\x8b" if hasattr(raw, "peek") else False
        f: IO[bytes] = gzip.GzipFile(fileobj=raw) if compressed else raw
        n = 0
        try:
            for n, line in enumerate(f, 1):
                try:
                    ev = json.loads(line.decode("ascii"))
                except (json.JSONDecodeError, UnicodeDecodeError) as exc:
                    raise TraceError(f"{path}:{n}: not a JSON line ({exc})") from None
                if not isinstance(ev, dict) or "ev" not in ev:
                    raise TraceError(f"{path}:{n}: not a trace event (no 'ev')")
                if n == 1 and ev["ev"] != "meta":
                    raise TraceError(f"{path}:1: the first line must be the meta event")
                yield ev
        except (OSError, EOFError, zlib.error) as exc:   # a damaged or truncated gzip
            raise TraceError(f"{path}: unreadable after line {n}: {exc}") from None
        if n == 0:
            raise TraceError(f"{path}: empty trace (no meta line)")
