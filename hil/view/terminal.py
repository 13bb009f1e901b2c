"""The textual driver of the live views (``rprs monitor``, ``rprs father`` at a terminal).

textual's Linux driver, with two things a terminal user meets put right:

* **Its size from the terminal it draws on.** textual asked ``shutil.get_terminal_size()``,
  which looks at *stdout*: with stdout sent to a file (``rprs monitor --json > summary.json``,
  which docs/monitor.md offers) it fell back to 80x24 whatever the terminal, and kept it
  through every resize. The size is now that of the terminal the view draws on (stderr), else
  stdin's, else stdout's.
* **A terminal that goes away.** Closing the terminal (its window, ``tmux kill-session``, an
  ssh link dropped) sends SIGHUP, which quits the view, but every write to the dead terminal
  fails (EIO): textual's writer thread died of the first one, its queue filled, and the next
  write blocked the app for ever, a process left running with its trace still ``.partial``.
  Writes to a terminal that has gone are now dropped, so the view quits as with ``q``.
"""
from __future__ import annotations

import os
import sys
from typing import IO, Any

from textual.drivers.linux_driver import LinuxDriver


class _TerminalOutput:
    """The file textual's writer thread writes to: a write or flush that fails (the terminal
    closed) marks the terminal ``gone`` and drops what follows."""

    def __init__(self, file: IO[str]) -> None:
        self._file = file
        self.gone = False

    def write(self, text: str) -> None:
        if self.gone:
            return
        try:
            self._file.write(text)
        except (OSError, ValueError):          # EIO from a hung-up terminal; a closed file
            self.gone = True

    def flush(self) -> None:
        if self.gone:
            return
        try:
            self._file.flush()
        except (OSError, ValueError):
            self.gone = True

    def fileno(self) -> int:
        return self._file.fileno()

    def isatty(self) -> bool:
        return not self.gone and self._file.isatty()


def terminal_size() -> tuple[int, int] | None:
    """(columns, lines) of the terminal the view draws on: stderr's, else stdin's, else
    stdout's; None if none of them is a terminal."""
    for f in (sys.__stderr__, sys.__stdin__, sys.__stdout__):
        if f is None:
            continue
        try:
            size = os.get_terminal_size(f.fileno())
        except (AttributeError, ValueError, OSError):
            continue
        if size.columns and size.lines:
            return size.columns, size.lines
    return None


class TerminalDriver(LinuxDriver):
    """textual's Linux driver, sized by the terminal it draws on and quiet once it is gone."""

    def __init__(self, app: Any, **kwargs: Any) -> None:
        super().__init__(app, **kwargs)
        stderr = sys.__stderr__
        assert stderr is not None               # (textual draws on it)
        # textual types its ``_file`` as the text file itself; the wrapper stands in for it
        self._file = _TerminalOutput(stderr)    # type: ignore[assignment]

    def _get_terminal_size(self) -> tuple[int, int]:
        return terminal_size() or super()._get_terminal_size()


def driver_for(base: type) -> type:
    """The driver a live view runs with: ``TerminalDriver`` where textual would use its Linux
    driver, ``base`` otherwise (another platform; the tests' headless driver)."""
    return TerminalDriver if base is LinuxDriver else base
