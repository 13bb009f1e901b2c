"""The father's orders as a person follows them: each order's state from submission to its end,
with the reason and the time it took, and the robots' replies decoded (``rprs father``).

An order goes ``queued`` (submitted to the MAC) -> ``sent`` (its first frame on air) ->
``acknowledged`` (the robot's ``ack``) -> ``done`` (the robot's ``done()`` notice, protocol 3.0),
``replied`` (the answer to ``status()``), ``failed`` (no acknowledgement after the MAC's
attempts, or the robot's ``fail(code)`` with that order), or ``unreported`` (acknowledged, and
no report :data:`REPORT_WITHIN_S` later: :meth:`OrderBook.expire`). An order of ``act(n,0)`` ends
when the robot broadcasts ``act(n,1)``; ``stop()``, which the robot carries out at once, when it
reports ``done()stop()`` (a child with no CAN side answers ``fail(42)``); a broadcast
(destination 7), and every order in the paper profile (nothing is acknowledged there), ends
``sent-only``. An order that never reached
the MAC ends ``refused`` at once, with the reason: a bad order line, a full queue at a terminal
(piped input waits for room instead), or a father PC standing by (docs/protocol.md clause 50).
A message of several commands (``1 joint(1,20)joint(2,30)``) is followed command by command, as the
robot reports each on
its own (docs/dispatcher.md): it ends when every one has, ``failed`` at the first failure.
Times are seconds since the order was queued (the station's clock). The robot's answer proves
the order arrived: an answer that comes before the acknowledgement (a lost ack on a lossy
channel, retransmitted later) marks the order ``acknowledged`` on the same tick, before its
end.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from firmware_model.radio.content import Command
from firmware_model.radio.frame import BROADCAST
from firmware_model.radio.mac import (
    UNACKNOWLEDGED, Deliver, Disable, Message, ModeChange, Outcome, Transmit,
)
from firmware_model.radio.mac_events import LateAck
from firmware_model.timing import TICK_HZ

FAIL_REASONS = {
    1: "target out of the arm's reach", 2: "outside a joint's limits",
    3: "parameter out of range", 30: "no submodule answers (CAN side dead or absent)",
    40: "the CAN controller went bus-off", 41: "the CAN bus is blocked: the child is off it",
    42: "the child has no CAN side",
}
"""The child's failure codes (docs/dispatcher.md); 10+n, 20+n, 30+n name submodule n."""

NODE_NAMES = {1: "joint 1", 2: "joint 2", 3: "joint 3", 4: "joint 4", 5: "wheel", 6: "paw"}
TERMINAL = frozenset({"done", "replied", "failed", "sent-only", "unreported", "refused"})
FINAL_STATES = ("done", "replied", "sent-only", "failed", "unreported", "refused")
"""The final states in the order the closing line counts them."""
SUCCEEDED = frozenset({"done", "replied", "sent-only"})
"""What counts as success (``rprs father --exit-when-done`` exits 0 only if every order ended
so): the robot reported it done, or replied; ``sent-only`` where nothing can acknowledge it (a
broadcast, the paper profile)."""
REPORT_WITHIN_S = 60.0
"""Seconds after its acknowledgement by which an order is reported on, or never will be: the
child reports every job it runs done or failed within twice its planned time + 1 s (at most
about 13 s: a joint's whole range at its rated speed), and no report at all for a move to where
the arm already is or an order replaced by a newer one (docs/dispatcher.md)."""
REPORTED = frozenset({"movex", "movey", "movez", "moveto", "joint", "wheel", "paw", "status",
                      "stop"})
"""Commands the robot reports on by themselves: ``done()`` and the command (``stop()`` as soon
as it is carried out), the reply to ``status()``, or ``fail(code)`` and the command;
``act(n,0)`` is reported by ``act(n,1)``. Any other command is done once acknowledged."""


def _reported(c: Command) -> bool:
    return c.name in REPORTED or (c.name == "act" and len(c.args) == 2 and c.args[1] == 0)


def fail_reason(code: int) -> str:
    """A failure code in words."""
    if code in FAIL_REASONS:
        return FAIL_REASONS[code]
    base, n = divmod(code, 10)
    node = NODE_NAMES.get(n)
    if node is not None and base in (1, 2, 3):
        return f"{node} " + ("reported a fault", "refused the command",
                             "did not respond")[base - 1]
    return "unknown code"


def describe_reply(commands: tuple[Command, ...]) -> str:
    """A status reply in words: ``joint 1 12.5 deg, joint 2 not responding, ..."""
    parts = []
    for c in commands:
        if c.name == "joint":
            parts.append(f"joint {c.args[0]} {float(c.args[1]):g} deg")
        elif c.name == "wheel":
            parts.append(f"wheel {float(c.args[0]):g} mm/s")
        elif c.name == "paw":
            parts.append("paw open" if c.args[0] else "paw closed")
        elif c.name == "fail":
            parts.append(f"fail({c.args[0]}): {fail_reason(int(c.args[0]))}")
        else:
            parts.append(c.text())
    return ", ".join(parts)


@dataclass
class Order:
    """One order of the father: ``#id -> dst commands`` and where it stands."""

    id: int
    dst: int | None                   # None: a line that named no destination
    text: str
    message: Message | None           # None: refused before it reached the MAC
    queued: int                       # tick
    state: str = "queued"
    reason: str = ""
    reply: str = ""
    ended: int | None = None
    history: list[tuple[int, str]] = field(default_factory=list)
    open_parts: list[str] = field(default_factory=list)   # commands not yet reported on
    expect: dict[int, list[str]] = field(default_factory=dict)
    """A broadcast: each robot it went to (the ring when it was first sent, less those that
    never acknowledged it) -> the commands that robot has yet to report on. Its reports are
    news (the broadcast ended ``sent-only``), but they answer it, not a later order."""

    def seconds(self, now: int) -> float:
        return (now - self.queued) / TICK_HZ

    @property
    def finished(self) -> bool:
        return self.state in TERMINAL


class OrderBook:
    """Follows the father station's orders from its observer's actions (call ``observe``
    from the station's observer, ``submitted`` with each message the station queued).
    ``on_change(order, now)`` is called at every change of state."""

    def __init__(self, on_change: Callable[[Order, int], None] | None = None,
                 on_news: Callable[[Deliver, int], None] | None = None) -> None:
        self.orders: list[Order] = []
        self.on_change = on_change
        self.on_news = on_news
        self._by_msg: dict[int, Order] = {}
        self._dropped: dict[int, int] = {}       # robot -> tick the ring last dropped it
        self._left: list[tuple[int, str]] = []   # (tick, why) the father went back to LISTEN

    def open_orders(self) -> list[Order]:
        return [o for o in self.orders if not o.finished]

    def refused(self, text: str, dst: int | None, reason: str, now: int) -> Order:
        """An order line that never reached the MAC: a record that ends ``refused`` at once."""
        o = Order(len(self.orders) + 1, dst, text, None, now)
        self.orders.append(o)
        self._set(o, "refused", now, reason)
        return o

    def counts(self) -> dict[str, int]:
        """How many orders are in each final state, and ``open`` those not ended yet."""
        out = dict.fromkeys(FINAL_STATES, 0)
        for o in self.orders:
            if o.finished:
                out[o.state] += 1
        out["open"] = len(self.orders) - sum(out.values())
        return out

    def all_succeeded(self) -> bool:
        """Every order ended in success (:data:`SUCCEEDED`); True with no orders at all."""
        return all(o.state in SUCCEEDED for o in self.orders)

    def closing_line(self) -> str:
        """``orders: 40 (done 0, replied 0, sent-only 0, failed 40, unreported 0, refused 0,
        open 0)``."""
        c = self.counts()
        return f"orders: {len(self.orders)} (" + ", ".join(f"{k} {v}" for k, v in c.items()) \
            + ")"

    def submitted(self, msg: Message, now: int) -> Order:
        o = Order(len(self.orders) + 1, msg.dst, "".join(c.text() for c in msg.commands), msg,
                  now, open_parts=[c.text() for c in msg.commands if _reported(c)])
        self.orders.append(o)
        self._by_msg[id(msg)] = o
        self._set(o, "queued", now)
        return o

    def observe(self, a: object, now: int) -> None:
        if isinstance(a, Transmit):
            f = a.frame
            for o in self.open_orders():
                m = o.message                   # (a queued order has its message)
                if o.state == "queued" and m is not None and m.num == f.num and m.dst == f.dst:
                    if o.dst == BROADCAST:
                        # a broadcast act(n,0) is a notice no robot carries out (clause 19a):
                        # no act(n,1) answers it
                        owed = [p for p in o.open_parts if not p.startswith("act(")]
                        o.expect = {r: list(owed) for r in m.awaiting if owed}
                    self._set(o, "sent", now)
        elif isinstance(a, Outcome):
            ended = self._by_msg.get(id(a.message))
            if ended is None or ended.finished:
                return
            for r in a.message.awaiting:        # never acknowledged: it may not have it
                ended.expect.pop(r, None)
            if a.delivered:
                self._acknowledged(ended, now)
            elif a.message.state == UNACKNOWLEDGED or ended.dst == BROADCAST:
                self._set(ended, "sent-only", now, "nothing acknowledges it (paper profile or "
                          "broadcast)")
            else:
                self._set(ended, "failed", now, a.reason)
        elif isinstance(a, Deliver):
            self._news(a, now)
        elif isinstance(a, LateAck):
            # a failed order the robot has after all: its answer is owed to it (news), not
            # to the robot's next order
            for o in self.orders:
                if o.dst == a.src and o.state == "failed" and o.message is not None and \
                        o.message.num == a.num and o.message.state == "failed":
                    owed = [c.text() for c in o.message.commands]
                    if owed:
                        o.expect = {a.src: owed}
        elif isinstance(a, Disable):
            self._dropped[a.robot] = now
        elif isinstance(a, ModeChange) and a.mode == "listen":
            self._left.append((now, a.reason))

    def expire(self, now: int, within_s: float = REPORT_WITHIN_S) -> None:
        """End ``unreported`` every order acknowledged ``within_s`` seconds ago or more that
        the robot has not reported on: it never will. The reason says what the father saw
        that explains it: a ``stop()`` after it, the ring dropping the robot, or else the
        cases in which a robot reports nothing."""
        for o in self.open_orders():
            acked = _tick_of(o, "acknowledged")
            if acked is not None and (now - acked) / TICK_HZ >= within_s:
                self._set(o, "unreported", now, f"no report within {within_s:g} s of its "
                          f"acknowledgement: {self._why_unreported(o, acked)}")
        for o in self.orders:
            # a broadcast's answers not come by then never will (a robot already there):
            # left owed, they would take a later order's report with the same text
            if o.expect:
                sent = _tick_of(o, "sent")
                if sent is not None and (now - sent) / TICK_HZ >= within_s:
                    o.expect.clear()

    def _why_unreported(self, o: Order, acked: int) -> str:
        """What the father saw after ``o``'s acknowledgement that explains a missing report
        (:meth:`_explained`); else the cases in which a robot reports nothing."""
        return self._explained(o, acked) or (
            "the robot reports none for a move to where the arm already is, or for an order a "
            "newer one replaced")

    def _explained(self, o: Order, acked: int) -> str | None:
        """What the father saw after ``o``'s acknowledgement that explains a missing report,
        the first of them: a later order to the robot that commands what ``o`` did (it
        replaced ``o``), a ``stop()``, the ring dropping the robot, the father itself out of
        the ring (a report sent then was not heard); None if nothing."""
        seen: list[tuple[int, str]] = []
        mine = _submodules(o)
        for p in self.orders:
            if p.id <= o.id or p.dst not in (o.dst, BROADCAST) or p.message is None:
                continue
            t = _tick_of(p, "acknowledged")
            if t is None or t < acked:
                continue
            if any(c.name == "stop" for c in p.message.commands):
                seen.append((t, f"#{p.id}'s stop() stopped it (the robot reports no order it "
                                f"stopped)"))
            elif p.dst == o.dst and _moves(o) and _moves(p) and (
                    mine is None or (_submodules(p) or mine) & mine):
                seen.append((t, f"#{p.id} ({p.text}) came before it was reported on: a newer "
                                f"order replaces it, and the robot reports no order replaced"))
        dropped = self._dropped.get(o.dst) if o.dst is not None else None
        if dropped is not None and dropped >= acked:
            seen.append((dropped, f"the ring dropped robot {o.dst} after it acknowledged it "
                                  f"(at {(dropped - o.queued) / TICK_HZ:.2f} s): it stopped, "
                                  f"or lost the order restarting"))
        left = next(((t, why) for t, why in self._left if t >= acked), None)
        if left is not None:
            seen.append((left[0], f"the father itself was out of the ring from "
                                  f"{(left[0] - o.queued) / TICK_HZ:.2f} s ({left[1]}): a "
                                  f"report sent then was not heard"))
        if seen:
            return min(seen, key=lambda x: x[0])[1]
        return None

    def close(self, now: int, why: str) -> None:
        """The father stops (``why``: the radio port went away, a signal, the duration): every
        order still open gets its final state, as every order line gets one. One never sent
        fails; one sent ends ``unreported``, with what the father saw first that explains a
        missing report, if anything (the ring dropped the robot)."""
        for o in self.open_orders():
            if o.state == "queued":
                self._set(o, "failed", now, f"never sent: {why}")
                continue
            acked = _tick_of(o, "acknowledged")
            seen = self._explained(o, acked) if acked is not None else None
            # what the father saw first explains it better than its own stop (the ring
            # dropped the robot, then the port went: the drop is the reason)
            self._set(o, "unreported", now, f"{why} before the robot reported on it" +
                      (f"; before that, {seen}" if seen else ""))

    def _acknowledged(self, o: Order, now: int) -> None:
        self._set(o, "acknowledged", now)
        if o.dst == BROADCAST:
            self._set(o, "sent-only", now, "a broadcast: no robot reports on it")
        else:
            self._maybe_done(o, now)

    def _arrived(self, o: Order, now: int) -> None:
        """The robot answered about ``o`` (sent: :meth:`_owner` gives no queued order): it has
        it, acknowledged or not yet."""
        if o.state == "sent":
            self._set(o, "acknowledged", now)

    def _part_ended(self, o: Order, part: str, now: int) -> None:
        """The robot reported on ``part`` of ``o`` (the whole order when ``part`` is its
        text); ``o`` ends once every reported command has."""
        if part == o.text:
            o.open_parts.clear()
        elif part in o.open_parts:
            o.open_parts.remove(part)
        self._maybe_done(o, now)

    def _maybe_done(self, o: Order, now: int) -> None:
        if not o.open_parts and o.state == "acknowledged":
            self._set(o, "replied" if o.reply else "done", now)

    @staticmethod
    def _about(o: Order, part: str) -> bool:
        return part == o.text or part in o.open_parts

    def _news(self, d: Deliver, now: int) -> None:
        """A message for the father: a status reply, a done()/fail() about an order, an
        act(n,1) notice, or other news. Each is about the oldest order the robot has had
        (sent, not queued) that it has yet to report on (:meth:`_owner`): a robot carries out
        and reports its orders in the order it takes them."""
        cmds = d.commands
        names = [c.name for c in cmds]
        matched = False
        if _is_status_reply(cmds) and d.dst != BROADCAST:
            # (before done/fail: a reply that starts with fail(31), joint 1 not answering)
            o = self._owner(d.src, lambda o, parts: "status()" in parts, "status()")
            if o is not None:
                matched = True
                self._arrived(o, now)
                o.reply = describe_reply(cmds)
                self._part_ended(o, "status()", now)
        elif names and names[0] in ("done", "fail") and len(cmds) >= 2:
            about = "".join(c.text() for c in cmds[1:])
            o = self._owner(d.src, lambda o, parts: about in parts or about == o.text, about)
            if o is not None:
                matched = True
                self._arrived(o, now)
                if names[0] == "done":
                    # (a done order commanded its submodules; a refusal, fail(2), did not)
                    self._replaced_before(o, now)
                    self._part_ended(o, about, now)
                else:
                    code = int(cmds[0].args[0])
                    part = "" if about == o.text else f": {about}"
                    self._set(o, "failed", now, f"fail({code}): {fail_reason(code)}{part}")
        elif names[:1] == ["act"] and len(cmds[0].args) == 2 and cmds[0].args[1] == 1:
            about = f"act({cmds[0].args[0]},0)"
            o = self._owner(d.src, lambda o, parts: about in parts, about)
            if o is not None:
                matched = True
                self._arrived(o, now)
                self._part_ended(o, about, now)
        if not matched and self.on_news is not None:
            self.on_news(d, now)

    def _replaced_before(self, o: Order, now: int) -> None:
        """The robot reported on ``o``: an older order of one submodule to it that ``o``
        commanded too (``joint(2,-5)`` before ``joint(2,100)``), still open, was replaced
        before it was carried out. Had it been carried out, its report would have come
        first: the robot reports in the order its orders finish. It ends ``unreported``
        now, so that a later report with its text (``joint(2,-5)`` again) goes to the order
        it is about, not to it."""
        mine = _submodules(o)
        if not mine:
            return
        for p in self.orders:
            if p is o:
                break
            if not (_submodules(p) or set()) & mine or p.state == "queued":
                continue
            if p.dst == o.dst and not p.finished:
                acked = _tick_of(p, "acknowledged")
                dropped = self._dropped.get(p.dst) if p.dst is not None else None
                if acked is not None and dropped is not None and dropped >= acked:
                    # the robot left the ring after taking it (restarted, or stopped): its
                    # report may have been lost, not the order replaced
                    self._set(p, "unreported", now, self._why_unreported(p, acked))
                else:
                    self._set(p, "unreported", now, f"replaced by #{o.id} before it was "
                              f"carried out: the robot reports no order a newer one replaced")
            elif p.dst == BROADCAST and o.dst in p.expect:
                del p.expect[o.dst]           # its answer to the broadcast will not come

    def _owner(self, robot: int, pred: Callable[[Order, list[str]], bool],
               part: str) -> Order | None:
        """The order ``robot``'s report on ``part`` is about: the oldest order it has had
        (sent or further: never a queued one, which it cannot have) whose commands not yet
        reported on ``pred`` takes: an open order to it, or a broadcast it was sent to and
        has not reported on yet. A broadcast's report is consumed there (the broadcast ended
        ``sent-only``; its reports are news) and None is returned: one robot's answer to a
        broadcast is no answer to a later order of its own."""
        for o in self.orders:
            if o.state == "queued" or o.message is None:
                continue
            if o.dst == robot and not o.finished and pred(o, o.open_parts):
                return o
            if o.dst == BROADCAST or o.expect:      # (a failed order acknowledged late)
                parts = o.expect.get(robot)
                if parts and pred(o, parts):
                    if part in parts:
                        parts.remove(part)
                    else:
                        parts.clear()           # a report on the whole message
                    if not parts:
                        del o.expect[robot]
                    return None
        return None

    def _set(self, o: Order, state: str, now: int, reason: str = "") -> None:
        if o.state == state and state != "queued":
            return
        o.state, o.reason = state, reason or o.reason
        o.history.append((now, state))
        if state in TERMINAL:
            o.ended = now
        if self.on_change is not None:
            self.on_change(o, now)


def _tick_of(o: Order, state: str) -> int | None:
    """The tick ``o`` first reached ``state``, if it did."""
    return next((t for t, st in o.history if st == state), None)


def _submodules(o: Order) -> set[int] | None:
    """The submodules ``o`` commands, where its commands say exactly (``joint(n,..)`` joint
    n, ``wheel`` 5, ``paw`` 6); None for any other (a Cartesian move or an action commands
    the joints its plan moves, which only the robot knows)."""
    if o.message is None:
        return None
    out: set[int] = set()
    for c in o.message.commands:
        if c.name == "joint" and c.args:
            out.add(int(c.args[0]))
        elif c.name in ("wheel", "paw"):
            out.add(5 if c.name == "wheel" else 6)
        else:
            return None
    return out


MOVES = frozenset({"movex", "movey", "movez", "moveto", "joint", "wheel", "paw", "act"})
"""Orders that command submodules: a later one of them may replace an earlier one."""


def _moves(o: Order) -> bool:
    return o.message is not None and any(c.name in MOVES for c in o.message.commands)


def _is_status_reply(cmds: tuple[Command, ...]) -> bool:
    """The answer to ``status()`` (docs/dispatcher.md): a value or ``fail(30+n)`` for each
    submodule, joints 1-4, the wheel and the paw, with at least one value; no order named."""
    names = [c.name for c in cmds]
    return len(cmds) == 6 and any(n in ("joint", "wheel", "paw") for n in names) and all(
        n in ("joint", "wheel", "paw") or (n == "fail" and len(c.args) == 1 and
                                          31 <= int(c.args[0]) <= 36)
        for n, c in zip(names, cmds))


def book_keeper(book: OrderBook) -> Callable[[Any, object, int], None]:
    """A station observer that feeds ``book`` (RadioStation.add_observer)."""
    def observe(st: Any, a: object, now: int) -> None:
        if type(a) is Message and a.src == st.id:
            book.submitted(a, now)
        else:
            book.observe(a, now)
    return observe
