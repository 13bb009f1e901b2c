"""``rprs father`` at a terminal: a live view of the ring and of the orders (textual).

* a header, refreshed 5 times a second: the father's mode (a standby PC says it refuses new
  orders), the ring as it sees it, whose turn it is (a member's, only while the father is a
  member), and its orders still open;
* the story below it: one line for each change of an order's state and of the ring (the same
  lines as the plain console, hil/view/father.py), replies decoded;
* an order line at the bottom (``DST COMMANDS``), with the usual editing keys, a history (up
  and down walk through the orders typed before, in this run and earlier ones, kept in the
  same file as the plain console's readline history) and the command names completed (Tab).

The firmware runs in the runner's thread; the app only reads what it shows and hands typed
orders to ``submit`` (which the caller makes thread-safe). Ctrl-C or ``ctrl+q`` quits, and
``rprs father`` then stops the firmware and prints its closing lines.
"""
from __future__ import annotations

import os
from collections import deque
from typing import Callable

from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.suggester import Suggester
from textual.widgets import Input, RichLog, Static

HISTORY_LIMIT = 1000


class CommandSuggester(Suggester):
    """Completes the command being typed (after the destination, or after another command's
    ``)``) from the command table (firmware_model/radio/content.py): ``1 jo`` suggests
    ``1 joint(``. One name only: none while two or more start with what is typed."""

    def __init__(self) -> None:
        super().__init__(use_cache=False, case_sensitive=True)
        from firmware_model.radio.content import COMMANDS
        self.names = sorted(COMMANDS)

    async def get_suggestion(self, value: str) -> str | None:
        head, _, word = value.rpartition(" ")
        if ")" in word:
            head, word = value[:value.rindex(")") + 1], value[value.rindex(")") + 1:]
        elif not head:
            return None                   # the destination comes first
        if not word or not word.isalpha():
            return None
        found = [n for n in self.names if n.startswith(word)]
        if len(found) != 1 or found[0] == word:
            return None
        return value + found[0][len(word):] + "("


class OrderInput(Input):
    """An order line with a history (up/down recall earlier orders) and the command names
    completed: the suggestion shows in grey, Tab (or right arrow at the end) takes it."""

    BINDINGS = [Binding("up", "older", "older order", show=False),
                Binding("down", "newer", "newer order", show=False),
                Binding("tab", "complete", "complete", show=False)]

    def __init__(self, history: list[str], **kw) -> None:
        super().__init__(placeholder="DST COMMANDS, e.g. 1 joint(2,60) or 1 status() "
                         "(Tab completes a command)", suggester=CommandSuggester(), **kw)
        self.history = history
        self._at = len(history)

    def action_complete(self) -> None:
        """Take the suggestion, if any (Tab does not move the focus: the view has one field)."""
        if self._suggestion:
            self.value = self._suggestion
            self.cursor_position = len(self.value)

    def remember(self, line: str) -> None:
        if line and (not self.history or self.history[-1] != line):
            self.history.append(line)
        self._at = len(self.history)

    def action_older(self) -> None:
        if self._at > 0:
            self._at -= 1
            self.value = self.history[self._at]
            self.cursor_position = len(self.value)

    def action_newer(self) -> None:
        if self._at < len(self.history):
            self._at += 1
            self.value = self.history[self._at] if self._at < len(self.history) else ""
            self.cursor_position = len(self.value)


class FatherApp(App):
    """The father's console. ``submit(line)`` queues a typed order and returns None or the
    reason it was refused; ``status()`` gives the header's text; ``ended()``, True once the
    firmware has stopped by itself, ends the view."""

    CSS = """
    #head { height: 3; background: $boost; padding: 0 1; }
    #log { height: 1fr; }
    OrderInput { dock: bottom; }
    """
    BINDINGS = [Binding("ctrl+q", "quit", "quit"),
                # Ctrl-C stops it, as it stops every rprs process (textual's own ctrl+c only
                # said "Press ctrl+q", and the order line's took it for copy): a priority
                # binding comes before both. super+c still copies.
                Binding("ctrl+c", "quit", "quit", show=False, priority=True)]

    def get_driver_class(self):
        """textual's driver, quiet once the terminal has closed (hil/view/terminal.py): the
        SIGHUP then stops the firmware and the view quits, where a write to the dead
        terminal could block it for ever."""
        from .terminal import driver_for
        return driver_for(super().get_driver_class())

    def __init__(self, submit: Callable[[str], str | None], status: Callable[[], str],
                 history_file: str | None = None, rate: float = 5.0,
                 ended: Callable[[], bool] | None = None) -> None:
        super().__init__()
        self._ended = ended
        self._submit = submit
        self._status = status
        self._rate = rate
        self.history_file = history_file
        self.history: list[str] = _read_history(history_file)
        self.lines: list[str] = []           # what the story shows (tests read it)
        self._posted: deque[str] = deque()   # from other threads, shown at the next refresh
        self._head = ""

    def compose(self) -> ComposeResult:
        yield Static(self._status(), id="head")
        yield RichLog(id="log", wrap=True, markup=False)
        yield OrderInput(self.history, id="order")

    def on_mount(self) -> None:
        self.title = "rprs father"
        self.query_one(OrderInput).focus()
        self.set_interval(1 / self._rate, self.refresh_head)

    def refresh_head(self) -> None:
        """The header again, and the story lines other threads posted since; the view quits
        once ``ended()`` says the firmware has stopped (``--duration``, a lost port)."""
        if self._ended is not None and self._ended():
            self.exit()
            return
        while self._posted:
            self.add_line(self._posted.popleft())
        text = self._status()
        if text != self._head:                 # redraw only what changed
            self._head = text
            self.query_one("#head", Static).update(text)

    def add_line(self, text: str) -> None:
        """A line of the story (call from the app's thread; from others: ``post_line``)."""
        self.lines.append(text)
        try:
            self.query_one("#log", RichLog).write(text)
        except Exception:                     # noqa: BLE001 - the view is being taken down
            pass

    def post_line(self, text: str) -> None:
        """``add_line`` from another thread (the runner's). It never waits for the view: the
        line is queued and shown at the next refresh, so a busy view cannot hold up the
        firmware's real-time thread."""
        self._posted.append(text)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        line = event.value.strip()
        box = self.query_one(OrderInput)
        box.value = ""
        if not line:
            return
        box.remember(line)
        why = self._submit(line)
        if why:
            self.add_line(f"not sent: {line}: {why}")

    def on_unmount(self) -> None:
        _write_history(self.history_file, self.history)


def _read_history(path: str | None) -> list[str]:
    if not path:
        return []
    try:
        with open(os.path.expanduser(path), encoding="utf-8", errors="replace") as f:
            return [line.rstrip("\n") for line in f if line.strip()][-HISTORY_LIMIT:]
    except OSError:
        return []


def _write_history(path: str | None, history: list[str]) -> None:
    if not path:
        return
    try:
        with open(os.path.expanduser(path), "w", encoding="utf-8") as f:
            f.writelines(line + "\n" for line in history[-HISTORY_LIMIT:])
    except OSError:
        pass


class LinesTo:
    """A text stream whose whole lines go to ``post`` (FatherConsole writes here when the app
    shows the story)."""

    def __init__(self, post: Callable[[str], None]) -> None:
        self._post = post
        self._part = ""

    def write(self, s: str) -> int:
        self._part += s
        *lines, self._part = self._part.split("\n")
        for line in lines:
            self._post(line)
        return len(s)

    def flush(self) -> None:
        pass
