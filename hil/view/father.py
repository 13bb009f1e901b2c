"""``rprs father`` for a person: one line for each thing worth knowing (an order's change of
state, a reply, a robot joining or dropped), never a line per frame. ``--json`` gives the
machine's stream instead, ``--quiet`` only the orders' ends (docs/bench.md)."""
from __future__ import annotations

import json
from typing import Any, Callable, Protocol

from firmware_model.radio.frame import BROADCAST
from firmware_model.radio.mac import Deliver, Disable, Join, ModeChange
from firmware_model.station import RadioStation, Stalled
from firmware_model.timing import TICK_HZ

from ..bench.orders import Order, describe_reply


HELP_WORDS = ("help", "?")
"""An order line that is one of these asks for :func:`order_help` instead."""


def order_help() -> list[str]:
    """The order line's form and every application command (firmware_model/radio/content.py,
    docs/protocol.md §3.4), one line each: what ``help`` prints at the father's prompt."""
    from firmware_model.radio.content import COMMANDS
    out = ["an order: DST COMMANDS, DST a robot 1-6 or 7 for all, e.g. '2 movex(10)', "
           "'1 joint(1,20)paw(1)', '7 status()'; ↑/↓ recall earlier orders; Ctrl-C quits"]
    for name, spec in sorted(COMMANDS.items()):
        if spec.layer != "app":
            continue
        params = ", ".join(p.name + (f" [{p.unit}]" if p.unit else "") for p in spec.params)
        out.append(f"  {name}({params}): {spec.doc}")
    return out


class Tee:
    """A line sink that writes to several (the screen and ``--log FILE``). A sink after the
    first that cannot be written (the disk filled) is dropped and ``on_error(exc)`` told
    once; the first sink's errors (stdout's reader gone) go to the caller."""

    def __init__(self, *sinks: "LineSink",
                 on_error: Callable[[OSError], None] | None = None) -> None:
        self.sinks = list(sinks)
        self.on_error = on_error

    def write(self, s: str, /) -> int:
        for i, sink in enumerate(list(self.sinks)):
            self._do(i, sink, sink.write, s)
        return len(s)

    def flush(self) -> None:
        for i, sink in enumerate(list(self.sinks)):
            self._do(i, sink, sink.flush)

    def _do(self, i: int, sink: "LineSink", act: Callable[..., Any], *args: Any) -> None:
        if i == 0 or self.on_error is None:
            act(*args)
            return
        try:
            act(*args)
        except OSError as exc:
            if sink in self.sinks:
                self.sinks.remove(sink)
                self.on_error(exc)


def _who(r: int) -> str:
    return "all" if r == BROADCAST else "father 0" if r == 0 else f"R{r}"


class LineSink(Protocol):
    """Where the story goes: a text file (stdout), or the app's story pane (``LinesTo``)."""

    def write(self, s: str, /) -> object: ...

    def flush(self) -> object: ...


class FatherConsole:
    """Prints the father's story to ``out`` in ``mode`` ``human``, ``quiet`` or ``json``."""

    def __init__(self, out: LineSink, mode: str = "human") -> None:
        if mode not in ("human", "quiet", "json"):
            raise ValueError(f"mode {mode!r}")
        self.out = out
        self.mode = mode

    def _line(self, now: int, text: str) -> None:
        self.out.write(f"{now / TICK_HZ:8.2f} s  {text}\n")
        self.out.flush()

    def order(self, o: Order, now: int) -> None:
        """An order changed state (OrderBook's on_change)."""
        if self.mode == "json":
            ev = {"t": now, "ev": "order", "id": o.id, "dst": o.dst, "order": o.text,
                  "state": o.state, "seconds": round(o.seconds(now), 3)}
            if o.reason:
                ev["reason"] = o.reason
            if o.reply:
                ev["reply"] = o.reply
            self.out.write(json.dumps(ev, separators=(",", ":")) + "\n")
            self.out.flush()
            return
        if self.mode == "quiet" and not o.finished:
            return
        if o.dst is None:                      # a line that named no destination
            self._line(now, f"#{o.id} {o.text!r}: {o.state}: {o.reason}")
            return
        head = f"#{o.id} -> {_who(o.dst)} {o.text}: {o.state}"
        took = f"{o.seconds(now):.2f} s"
        if o.state == "refused":
            tail = f": {o.reason}"
        elif o.state == "queued":
            tail = ""
        elif o.state == "sent":
            assert o.message is not None       # (a sent order went through the MAC)
            tail = f" (Number {o.message.num:02d})"
        elif o.state == "replied":
            tail = f" in {took}: {o.reply}"
        elif o.state in ("failed", "sent-only", "unreported"):
            tail = f" after {took}: {o.reason}"
        else:
            tail = f" in {took}"
        self._line(now, head + tail)

    def news(self, d: Deliver, now: int) -> None:
        """A message for the father that is about no order of this session."""
        if self.mode == "human":
            self._line(now, f"{_who(d.src)} says: {describe_reply(d.commands)}")

    def ring(self, st: RadioStation, a: object, now: int) -> None:
        """The father's view of the ring changed (its station ``st``'s observer)."""
        if self.mode != "human":
            return
        if isinstance(a, Join):
            self._line(now, f"ring: {_who(a.robot)} {'rejoined' if a.again else 'joined'}")
        elif isinstance(a, Disable):
            self._line(now, f"ring: {_who(a.robot)} dropped after three missed turns")
        elif isinstance(a, ModeChange):
            ring = " ".join(_who(r) for r in st.mac.ring)
            note = ""
            if getattr(st.mac, "standby", False):
                note = "; standing by: new orders are refused until this PC takes over"
                held = st.mac.pending
                if held:
                    note += (f"; {held} held here go out if it does, else fail (expired) "
                             f"{st.mac.cfg.max_age // TICK_HZ} s after each was given")
            self._line(now, f"father: {a.mode} ({a.reason}); ring [{ring}]{note}")
        elif isinstance(a, Stalled):
            self._line(now, f"father: stalled {a.late / TICK_HZ:.2f} s (the process did not "
                            f"run); what it heard meanwhile is dropped, listening for the "
                            f"ring again")
