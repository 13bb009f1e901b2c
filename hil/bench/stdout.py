"""Standard output that says why it could not be written: a full disk or an I/O error is one
line and status 1 for every command (hil/cli/__init__.py, ``main``), as a reader gone away
(BrokenPipeError) ends every command quietly."""
from __future__ import annotations

from typing import Any, Callable, Iterable

__all__ = ["GuardedStdout", "StdoutFailed"]


class StdoutFailed(Exception):
    """Standard output could not be written for another reason than its reader going away (a
    full disk, an I/O error): one line and status 1 (``main``). Not an OSError, so that no
    command takes it for a failure of one of its own files."""


class GuardedStdout:
    """``sys.stdout`` while a command runs (``main``): a write or flush that fails, other
    than by the reader going away (BrokenPipeError: hil/cli/common.py, ``stdout_gone``), raises
    :class:`StdoutFailed` with the system's reason; everything else is the stream's."""

    def __init__(self, raw: Any) -> None:
        self.raw = raw

    def write(self, s: str) -> int:
        return _guarded(self.raw.write, s)

    def flush(self) -> None:
        _guarded(self.raw.flush)

    def writelines(self, lines: Iterable[str]) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.raw, name)


def _guarded(call: Callable[..., Any], *args: Any) -> Any:
    """``call(*args)`` on the stream: BrokenPipeError as it is, any other OSError as
    :class:`StdoutFailed`."""
    try:
        return call(*args)
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise StdoutFailed(exc.strerror or str(exc)) from None
