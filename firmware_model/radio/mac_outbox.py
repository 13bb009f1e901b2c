"""The rotational MAC's outbox (docs/protocol.md §4.7): submission, acknowledgements, and how a
message ends (delivered, failed, expired; a destination dropped or restarted). Functions of a
``RotationalMac``, bound as its methods in mac.py; the queue itself (``_queue``,
``_inflight``) is the MAC's state, and which message a turn carries is mac_frames.py's
``_pick_message``."""
from __future__ import annotations

from typing import TYPE_CHECKING, Iterable

from ..timing import FRAME_OVERHEAD
from .content import Command
from .frame import BROADCAST, FrameType
from .mac_config import check_submission
from .mac_events import LateAck, Message, Outcome, QueueFull, StandingBy, SubmitError

if TYPE_CHECKING:
    from .mac import RotationalMac


def submit(self: RotationalMac, dst: int, commands: Iterable[Command], now: int,
           type: int = FrameType.INSTRUCTION) -> Message:
    """Queue a message; raises SubmitError if it can never be sent in one turn."""
    commands, content = check_submission(self.id, dst, commands, type)
    limit = self.max_content - self._ext_len
    if len(content) > limit:
        raise SubmitError(
            f"Content of {len(content)} bytes makes a "
            f"{len(content) + FRAME_OVERHEAD + self.max_content - limit}-byte frame, longer "
            f"than one turn allows ({self.max_content + FRAME_OVERHEAD} bytes fit in Tmax"
            f"{', checksum included' if self.cfg.checksum else ''}"
            f"{', auth included' if self._key is not None else ''}); "
            f"split the message")
    if self.standby:
        pc = self.cfg.pc
        other = f"PC{3 - pc}" if self.cfg.paired else "another father PC on ID 0"
        raise StandingBy(f"PC{pc} is standing by: the active PC is {other}; give orders "
                         f"there, or here once this PC has taken over")
    if self.pending >= self.cfg.max_queue:
        raise QueueFull(f"queue full ({self.cfg.max_queue} messages pending)")
    msg = Message(self.id, dst, self._next_num, int(type), commands, content, now)
    self._next_num = (self._next_num + 1) % 100
    self._queue.append(msg)
    return msg


def _rebooted(self: RotationalMac, src: int, num: int, out: list) -> None:
    """``src`` sent a BOOT frame: it powered on, so its Numbers restart ('00' is the BOOT
    frame's own) and it forgot every Number it had heard (its BOOT frames are
    acknowledged: it sends no message before every member has). A message of ours in
    flight to it may have been delivered before the reboot and would be delivered again:
    it fails."""
    self._last_rx[src] = num
    m = self._inflight
    if m is not None and m.attempts:
        self._unawait(m, src, f"destination {src} restarted before acknowledging (after "
                      f"{m.attempts} attempt(s))", f"robot {src} restarted before "
                      f"acknowledging", out)


def _unawait(self: RotationalMac, m: Message, robot: int, unicast_reason: str,
             broadcast_reason: str, out: list) -> None:
    """``robot`` will never acknowledge ``m``: a unicast to it fails; a broadcast ends
    once nobody else is awaited (delivered if anyone acknowledged)."""
    if robot not in m.awaiting:
        return
    m.awaiting.discard(robot)
    if m.dst == robot:
        self._finish(m, False, unicast_reason, out)
    elif not m.awaiting:
        self._finish(m, bool(m.acked), "" if m.acked else broadcast_reason, out)


def _on_ack(self: RotationalMac, src: int, num: int, now: int, out: list) -> None:
    if self._announcing is not None and num == self._ann_num:
        self._ann_awaiting.discard(src)
        if not self._ann_awaiting:
            self._announced()
        return
    m = self._inflight
    if m is None or m.num != num or src not in m.awaiting:
        if self._failed_sent.get(src) == num:
            del self._failed_sent[src]
            out.append(LateAck(src, num))
        return
    m.awaiting.discard(src)
    m.acked.add(src)
    if not m.awaiting:
        self._finish(m, True, "", out)


def _finish(self: RotationalMac, m: Message, delivered: bool, reason: str, out: list) -> None:
    m.state = "delivered" if delivered else "failed"
    m.reason = reason
    if not delivered and m.attempts and m.dst != BROADCAST:
        self._failed_sent[m.dst] = m.num     # it went out: its robot may have it (LateAck)
    if self._inflight is m:
        self._inflight = None
    elif m in self._queue:
        self._queue.remove(m)
    out.append(Outcome(m, delivered, reason))


def _expire(self: RotationalMac, now: int, out: list) -> None:
    """Fail what is too old, also while this robot takes no turns (listening, standing
    by): every message ends within ``max_age`` whatever happens to the robot."""
    limit = now - self.cfg.max_age
    m = self._inflight
    if m is not None and m.submitted < limit:
        self._finish(m, False, f"expired: not acknowledged within "
                     f"{self.cfg.max_age // 16_000} ms", out)
    while self._queue and self._queue[0].submitted < limit:
        self._finish(self._queue[0], False, f"expired: not sent within "
                     f"{self.cfg.max_age // 16_000} ms", out)


def _others_number(self: RotationalMac, num: int, out: list) -> None:
    """The other PC of the father's pair sent its own message of Number ``num`` (clause 50:
    the pair shares ID 0's Numbers, and a PC never sends the other's message). An ``ack`` of
    ``num`` no longer tells the two apart: ours of that Number, in flight or queued, fails
    (it may have reached its destination: failed, not sent again), and a late ``ack`` of it
    is not taken for ours (``LateAck``)."""
    for m in [m for m in self.outbox if m.num == num]:
        self._finish(m, False, f"the other PC sent its own message {num:02d}: an "
                     f"acknowledgement of {num:02d} cannot say whose (after {m.attempts} "
                     f"attempt(s))", out)
    for r in [r for r, n in self._failed_sent.items() if n == num]:
        del self._failed_sent[r]


def _number_after_others(self: RotationalMac, num: int) -> int:
    """Our next Number after the other PC's ``num`` (clause 50): after it, and after each of
    our own messages still in the outbox, which keep their Numbers. Numbered ``num + 1``
    alone, a new message could repeat a queued one's Number (a PC that numbered messages
    while deaf, then stood by with them), and a destination that had the first would take
    the second for a duplicate (clause 48): acknowledged, never delivered."""
    nxt = (num + 1) % 100
    for m in self.outbox:                  # in the order they were numbered
        if (m.num - nxt) % 100 < 50:       # at or ahead of nxt (Numbers wrap at 100)
            nxt = (m.num + 1) % 100
    return nxt
