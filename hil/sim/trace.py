"""JSON Lines trace of a run: one event a line, schema in docs/trace.md.

The first line is the ``meta`` event; every later line has ``t`` (tick, non-decreasing) and
``ev``. Keys are written in a fixed order and numbers as integers, so the same seed gives a
byte-identical file.
"""
from __future__ import annotations

import errno
import gzip
import io
import json
import os
import stat
import zlib
from typing import IO, TYPE_CHECKING, Any, Iterator

from .events import TraceError, typed

if TYPE_CHECKING:
    from .events import Meta, OtherEvent, TraceEvent

TRACE_VERSION = 1


class _OutputRaw(io.FileIO):
    """The file under an :class:`OutputFile`'s buffer: a write that fails (a full disk) raises
    its OSError with ``filename`` the output's path, so that whoever writes several outputs at
    once can tell which one failed (the buffers write when they fill, deep inside a run)."""

    def __init__(self, tmp: str, output: str) -> None:
        super().__init__(tmp, "w")
        self.output = output

    def write(self, b):
        try:
            return super().write(b)
        except OSError as exc:
            if exc.filename is None:
                exc.filename = self.output
            raise


def partial_name(path: str) -> str:
    """The file an output to ``path`` is written to first: ``PATH.PID.partial``, this
    process's own, so that two runs writing one output each write a whole file of their own
    and the last to finish renames it over ``path`` (with one ``PATH.partial`` for both, their
    bytes mixed, or the first rename took the file from under the second)."""
    return f"{path}.{os.getpid()}.partial"


class OutputFile:
    """An output that appears whole or not at all: written to ``PATH.PID.partial`` beside the file
    ``path`` names (through a symlink: the link stays), renamed over it at :meth:`commit`,
    removed at :meth:`discard`. A ``path`` that names a device or a FIFO (``/dev/null``, a pipe
    to a reader) is written straight: a file renamed over it would replace it (as root,
    ``--trace /dev/null`` once replaced /dev/null with a regular file). A directory raises
    ``IsADirectoryError`` here, before anything is written, rather than at the rename after
    the whole run. ``binary``: bytes, else ASCII text with ``\n`` line ends. ``compress``:
    gzip-compressed (no name and no time in its header: the same bytes give the same file).
    An OSError from writing ``f`` or from :meth:`commit` has ``filename`` = ``path``: the
    output that failed."""

    def __init__(self, path: str, binary: bool = False, compress: bool = False) -> None:
        self.path = path
        try:
            mode = os.stat(path).st_mode          # through symlinks
        except FileNotFoundError:
            mode = None
        if mode is not None and stat.S_ISDIR(mode):
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), path)
        self.direct = mode is not None and not stat.S_ISREG(mode)
        self.final = path if self.direct else os.path.realpath(path)
        self.tmp = self.final if self.direct else partial_name(self.final)
        # open(tmp, "wb" or "w") but over _OutputRaw: the same buffer, the same bytes
        raw = _OutputRaw(self.tmp, path)
        try:
            size = os.fstat(raw.fileno()).st_blksize
            buf = io.BufferedWriter(raw, size if size > 1 else io.DEFAULT_BUFFER_SIZE)
        except BaseException:
            raw.close()
            raise
        self._buf = buf
        inner: Any = gzip.GzipFile(filename="", mode="wb", fileobj=buf, mtime=0) \
            if compress else buf
        self.f: IO = inner if binary else io.TextIOWrapper(
            inner, encoding="ascii", newline="\n", line_buffering=raw.isatty())

    def _close(self) -> None:
        """Close ``f`` and the buffer under it (a gzip layer leaves its file open)."""
        try:
            self.f.close()
        finally:
            self._buf.close()

    def commit(self) -> None:
        """Close the file and put it in place; OSError (``filename``: ``path``) if its last
        bytes cannot be written (a full disk) or it cannot be put in place, and then nothing
        is left."""
        try:
            self._close()
            if not self.direct:
                os.replace(self.tmp, self.final)
        except BaseException as exc:
            self.discard()
            if isinstance(exc, OSError):   # the rename names the partial file: name the output
                exc.filename, exc.filename2 = self.path, None
            raise

    def discard(self) -> None:
        """Close and remove the partial file (a device or FIFO is left as it is)."""
        try:
            self._close()
        except OSError:        # the bytes still buffered cannot be written (a full disk)
            pass
        if not self.direct:
            try:
                os.unlink(self.tmp)
            except FileNotFoundError:
                pass


class TraceWriter:
    """Writes events to ``path`` atomically: the file appears complete at ``close()`` or not at
    all (a run that fails leaves no partial trace behind; :class:`OutputFile`); gzip-compressed
    if its name ends in ``.gz`` (:func:`read_trace` reads both)."""

    def __init__(self, path: str) -> None:
        self.path = path
        self._out = OutputFile(path, compress=path.endswith(".gz"))
        self._f = self._out.f
        self._dumps = json.JSONEncoder(separators=(",", ":"), ensure_ascii=True).encode
        self.count = 0

    def write(self, ev: "TraceEvent | Meta") -> None:
        """Write one event (hil/sim/events.py) as its JSON line: a world's listener."""
        self._f.write(self._dumps(ev.record()))
        self._f.write("\n")
        self.count += 1

    def close(self) -> None:
        self._out.commit()

    def discard(self) -> None:
        self._out.discard()




def read_trace(path: str) -> Iterator[dict[str, Any]]:
    """Yield the events of a trace file (plain or gzip-compressed, told apart by the gzip
    magic bytes), checking the meta line comes first and gives this version (or none: a
    hand-made trace). A file that is not a trace (an image, a README, a truncated gzip) or
    another version's raises ``TraceError`` naming the line."""
    try:
        raw = open(path, "rb")
    except OSError as exc:
        raise TraceError(f"cannot read trace {path}: {exc.strerror}") from None
    with raw:
        compressed = raw.peek(2)[:2] == b"\x1f\x8b" if hasattr(raw, "peek") else False
        f: io.BufferedIOBase = gzip.GzipFile(fileobj=raw) if compressed else raw
        n = 0
        try:
            for n, line in enumerate(f, 1):
                try:
                    ev = json.loads(line.decode("ascii"))
                except (json.JSONDecodeError, UnicodeDecodeError) as exc:
                    raise TraceError(f"{path}:{n}: not a JSON line ({exc})") from None
                if not isinstance(ev, dict) or "ev" not in ev:
                    raise TraceError(f"{path}:{n}: not a trace event (no 'ev')")
                if n == 1:
                    if ev["ev"] != "meta":
                        raise TraceError(f"{path}:1: the first line must be the meta event")
                    v = ev.get("version", TRACE_VERSION)
                    if type(v) is not int or v != TRACE_VERSION:
                        raise TraceError(f"{path}:1: trace version {v!r}: this rprs reads "
                                         f"version {TRACE_VERSION}" + (
                                             " (a newer rprs wrote it)" if type(v) is int and
                                             v > TRACE_VERSION else ""))
                yield ev
        except (OSError, EOFError, zlib.error) as exc:   # a damaged or truncated gzip
            raise TraceError(f"{path}: unreadable after line {n}: {exc}") from None
        if n == 0:
            raise TraceError(f"{path}: empty trace (no meta line)")


def read_events(path: str) -> Iterator["TraceEvent | OtherEvent"]:
    """The events of a trace file, typed (hil/sim/events.py): the meta first, then each
    line read back with every field's type checked; TraceError names the line that is not
    an event."""
    return typed(read_trace(path))
