"""The project's child with one deliberate bug, for the conformance kit's tests (not a product
command): ``python tests/faulty_child.py FAULT child --id 1 --radio PORT ...`` patches the
rotational MAC, then runs ``rprs`` with the remaining arguments.

Faults (each one rule of docs/protocol.md broken, the rest of the child untouched):

- ``late-turn``: every frame's Header 20 ms after Ttrans (clause 23);
- ``long-length``: every frame's Length one more than its Content (clauses 11, 15);
- ``no-ack``: acknowledges nothing (clauses 36, 47);
- ``boot-01``: its BOOT frames are Number '01' (clause 29);
- ``no-stagger``: no R-stagger (nor R-pair) after an uncertain turn end (clause 44);
- ``late-answer``: its answer to an invitation 40 ms after Ttrans (clause 34);
- ``invite-every-turn``: it invites an absent robot of its gap in each of its turns, not in
  every P-th (clause 32);
- ``deaf-to-masks``: it reads no ``ring(mask)``, so a mask without its bit does not send it
  back to LISTEN, and a robot the mask adds is not admitted (clause 51);
- ``no-cut-off``: it never concludes its radio is cut off, however many turns in a row it
  missed with nothing heard (clause 40);
- ``early-takeovers``: a frame from a member after the owner it waits for is a takeover
  however early it comes, not one out of turn (clause 39);
- ``numbers-do-not-wrap``: a message is new only if its Number is above the last one heard
  from its sender, so '00' after '99' is taken for a duplicate (clauses 45, 48);
- ``own-numbers-skip-00``: its own message counter goes '99' then '01', as if '00' were kept
  for BOOT frames (clause 45; caught only by ``rprs conformance --wrap``);
- ``masks-never-drop``: a ``ring(mask)`` admits and sends it to LISTEN as it should, but never
  drops a member the mask leaves out, though it counted that member missing too (clause
  51.3);
- ``status-reply-type-2``: it answers ``status()`` (with its values, or ``fail(code)status()``
  without them) in a message of Type '2', a command, not '3' or '4' (clause 19a);
- ``silent-after-refused``: it refuses a forged or replayed frame, as it should, but does not
  take the turn that frame closed: it waits for the next robot's (clause 53, authenticated
  profile).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, Callable

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from firmware_model.radio import mac as mac_mod            # noqa: E402
from firmware_model.radio.frame import Frame, FrameType     # noqa: E402
from firmware_model.radio.mac_guard import unguarded        # noqa: E402
from firmware_model.timing import TICK_HZ                   # noqa: E402

MS = TICK_HZ // 1000
Mac = mac_mod.RotationalMac
Setter = Callable[[Any, str, Any], None]
FAULTS = ("late-turn", "long-length", "no-ack", "boot-01", "no-stagger", "late-answer",
          "invite-every-turn", "deaf-to-masks", "no-cut-off",
          "masks-never-drop", "early-takeovers", "numbers-do-not-wrap", "own-numbers-skip-00",
          "status-reply-type-2")
AUTH_FAULTS = ("silent-after-refused",)
"""Faults of the authenticated profile only (the kit's clause 53 step)."""


def _delay_switch(set_attr: Setter, ms: int, only_answers: bool) -> None:
    """Our Header ``ms`` later: the SWITCH phase (TXEN up, Ttrans to the first bit) lasts
    longer."""
    orig = Mac._my_turn

    def _my_turn(self, start, now, out):
        orig(self, start, now, out)
        if self.phase == mac_mod.SWITCH and (self._answering or not only_answers):
            self.deadline += ms * MS
    set_attr(Mac, "_my_turn", _my_turn)


def _long_length(set_attr: Setter) -> None:
    orig = Mac._build_frame

    def _build_frame(self, now, out):
        frame, data = orig(self, now, out)
        n = int(data[8:12]) + 1
        return frame, data[:8] + b"%04d" % n + data[12:]
    set_attr(Mac, "_build_frame", _build_frame)


def _no_ack(set_attr: Setter) -> None:
    orig = Mac._build_frame

    def _build_frame(self, now, out):
        self._acks = []
        return orig(self, now, out)
    set_attr(Mac, "_build_frame", _build_frame)


def _silent_after_refused(set_attr: Setter) -> None:
    orig = Mac.on_frame

    def on_frame(self, frame, first, end, now):
        out = orig(self, frame, first, end, now)
        if any(type(a) is mac_mod.Refused for a in out) and self.phase == mac_mod.HOLD:
            # the turn the refused frame closed is ours: wait, with no deadline, for a frame
            # of the next robot's instead (whoever takes the turn over)
            self.phase = mac_mod.WAIT
            self.owner = self.succ(self.id)
            self.turn_start = end
            self.deadline = None
        return out
    set_attr(Mac, "on_frame", on_frame)


def _boot_01(set_attr: Setter) -> None:
    orig = Mac._build_frame

    def _build_frame(self, now, out):
        frame, data = orig(self, now, out)
        if frame.type == FrameType.BOOT:
            if self._announcing == FrameType.BOOT:
                self._ann_num = 1              # it waits for the acks of what it sent
            frame = Frame(dst=frame.dst, src=frame.src, num=1, type=frame.type,
                          content=frame.content)
            data = frame.encode()
        return frame, data
    set_attr(Mac, "_build_frame", _build_frame)


def _no_stagger(set_attr: Setter) -> None:
    orig = Mac._next_turn

    def _next_turn(self, after, start, now, out, uncertain=False, not_before=None):
        orig(self, after, start, now, out)
    set_attr(Mac, "_next_turn", _next_turn)


def _invite_every_turn(set_attr: Setter) -> None:
    orig = Mac._poll_target

    def _poll_target(self):
        self._turns_since_poll = self.cfg.poll_every      # always due
        return orig(self)
    set_attr(Mac, "_poll_target", _poll_target)


def _deaf_to_masks(set_attr: Setter) -> None:
    set_attr(Mac, "_reconcile", lambda self, src, mask, now, out: None)


def _no_cut_off(set_attr: Setter) -> None:
    orig = Mac.on_timer

    def on_timer(self, now, rx_busy=False, last_rx=None, rx_began=None):
        self._silent = 0                   # it forgets the misses it counted with nothing heard
        return orig(self, now, rx_busy, last_rx, rx_began)
    set_attr(Mac, "on_timer", on_timer)


def _masks_never_drop(set_attr: Setter) -> None:
    orig = Mac._reconcile

    def _reconcile(self, src, mask, now, out):
        # every member of its ring read as in the mask (but itself: left out, it still goes)
        kept = sum(1 << r for r in self.ring if r != self.id)
        orig(self, src, mask | kept, now, out)
    set_attr(Mac, "_reconcile", _reconcile)


def _early_takeovers(set_attr: Setter) -> None:
    orig = Mac._takeover

    def _takeover(self, src, first):
        began, self.turn_start = self.turn_start, -(1 << 40)   # as if the turn began long ago
        try:
            return orig(self, src, first)
        finally:
            self.turn_start = began
    set_attr(Mac, "_takeover", _takeover)


class _Higher(int):
    """A remembered Number that a new one differs from only if it is higher."""

    def __ne__(self, other):
        return other > int(self)


class _NoWrap(dict):
    def get(self, key, default=None):
        v = super().get(key, default)
        return v if v is None else _Higher(v)


def _numbers_do_not_wrap(set_attr: Setter) -> None:
    orig = Mac.on_frame

    def on_frame(self, frame, first, end, now):
        if type(self._last_rx) is dict:
            self._last_rx = _NoWrap(self._last_rx)
        return orig(self, frame, first, end, now)
    set_attr(Mac, "on_frame", on_frame)


def _own_numbers_skip_00(set_attr: Setter) -> None:
    orig = Mac.submit

    def submit(self, *args, **kw):
        msg = orig(self, *args, **kw)
        if self._next_num == 0:
            self._next_num = 1
        return msg
    set_attr(Mac, "submit", submit)


def _status_reply_type_2(set_attr: Setter) -> None:
    """The dispatcher's answers to status() (a child with its CAN side), and a child without
    one's fail(42)status(), go out as Type '2'."""
    from firmware_model import child, dispatcher
    orig = dispatcher.Dispatcher._cmd_status

    def _cmd_status(self, src, c, now):
        n = len(self._radio)
        orig(self, src, c, now)
        self._radio[n:] = [(dst, cmds, 2) for dst, cmds, _ in self._radio[n:]]
    set_attr(dispatcher.Dispatcher, "_cmd_status", _cmd_status)
    radio_only = child.RadioOnlyChild._on_message

    def _on_message(self, d, now):
        submit = self.station.submit

        def as_command(dst, commands, type=2):
            return submit(dst, commands, 2 if any(c.name == "status" for c in commands)
                          else type)
        self.station.submit = as_command
        try:
            radio_only(self, d, now)
        finally:
            del self.station.submit
    set_attr(child.RadioOnlyChild, "_on_message", _on_message)


def patch(fault: str, set_attr: Setter = setattr) -> None:
    """Break ``fault``'s rule in the rotational MAC (for every robot of this process);
    ``set_attr``: how (pytest's ``monkeypatch.setattr`` undoes it after the test). The
    transition table's guard is taken off: a broken rule may move the MAC along no row."""
    unguarded(set_attr)
    {"late-turn": lambda s: _delay_switch(s, 20, False),
     "late-answer": lambda s: _delay_switch(s, 40, True),
     "long-length": _long_length, "no-ack": _no_ack, "boot-01": _boot_01,
     "no-stagger": _no_stagger, "invite-every-turn": _invite_every_turn,
     "deaf-to-masks": _deaf_to_masks, "no-cut-off": _no_cut_off,
     "masks-never-drop": _masks_never_drop, "early-takeovers": _early_takeovers,
     "numbers-do-not-wrap": _numbers_do_not_wrap,
     "own-numbers-skip-00": _own_numbers_skip_00,
     "status-reply-type-2": _status_reply_type_2,
     "silent-after-refused": _silent_after_refused}[fault](set_attr)


if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1] not in FAULTS + AUTH_FAULTS:
        sys.exit(f"usage: faulty_child.py {{{'|'.join(FAULTS + AUTH_FAULTS)}}} child ARGS...")
    patch(sys.argv[1])
    # a broken rule may move the MAC along no row of the transition table: that is the point
    os.environ.pop("RPRS_MAC_TABLE_GUARD", None)
    from hil.cli import main
    sys.exit(main(sys.argv[2:]))
