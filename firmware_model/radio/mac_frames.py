"""The rotational MAC's frame building (docs/protocol.md §4.4-§4.7): what this turn's one frame
carries (a message or a heartbeat, acknowledgements, an invitation or the ring mask; BOOT and
JOIN frames), which message goes (``_pick_message``), whom to invite (``_poll_target``), and
the sealing of a frame (checksum or authentication tag). Functions of a ``RotationalMac``,
bound as its methods in mac.py (a method so bound costs what one defined there does); also the
Content helpers its receiving side shares."""
from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING, Iterable

from . import auth as _auth
from .content import Command, cmd, format_content, parse_content, split_layers
from .frame import BROADCAST, Frame, FrameType
from .integrity import seal
from .mac_events import Message

if TYPE_CHECKING:
    from .mac import RotationalMac

HB_CACHE_MAX = 256
"""Heartbeat frames a MAC keeps built, by (Number, MAC Content, type): a bounded cache (the
simulator's snapshots walk it: hil/sim/quiet_ring.py)."""


@lru_cache(maxsize=2048)
def _layers(content: bytes) -> tuple[tuple[Command, ...], tuple[Command, ...]]:
    """Parse Content once per distinct byte string: every receiver of a frame shares it."""
    return split_layers(parse_content(content))


@lru_cache(maxsize=1024)
def _ack_len(ack: tuple[int, int]) -> int:
    """Content bytes of ``ack(src,num)``."""
    return len(cmd("ack", ack[0], ack[1]).text())


def _mask(ids: Iterable[int]) -> int:
    m = 0
    for i in ids:
        m |= 1 << i
    return m


def _unmask(mask: int) -> set[int]:
    return {i for i in range(7) if mask >> i & 1}


def _pick_message(self: RotationalMac, now: int, out: list) -> Message | None:
    """The message to carry this turn (retransmission first), failing what must fail."""
    cfg = self.cfg
    m = self._inflight
    if m is not None:
        if now - m.submitted > cfg.max_age:
            self._finish(m, False, f"expired: not acknowledged within "
                         f"{cfg.max_age // 16_000} ms", out)
        elif m.attempts >= cfg.max_attempts:
            missing = ",".join(str(r) for r in sorted(m.awaiting))
            self._finish(m, False, f"no acknowledgement from {missing} after "
                         f"{m.attempts} attempts", out)
        else:
            return m
    while self._queue:
        m = self._queue[0]
        if now - m.submitted > cfg.max_age:
            self._finish(m, False, f"expired: not sent within {cfg.max_age // 16_000} ms",
                         out)
            continue
        if m.dst != BROADCAST and m.dst not in self.ring:
            m.waited += 1
            if m.waited >= cfg.max_attempts:
                self._finish(m, False, f"destination {m.dst} not in the ring", out)
                continue
            return None
        if m.dst == BROADCAST and len(self.ring) < 2:
            m.waited += 1
            if m.waited >= cfg.max_attempts:
                self._finish(m, False, "broadcast with no other member in the ring", out)
                continue
            return None
        self._queue.pop(0)
        m.awaiting = {m.dst} if m.dst != BROADCAST else set(self.ring) - {self.id}
        self._inflight = m
        return m
    return None


def _poll_target(self: RotationalMac) -> int | None:
    """An absent team robot in the gap after me to invite this turn, if one is due."""
    cfg = self.cfg
    self._turns_since_poll += 1
    if not self.lone and self._turns_since_poll < cfg.poll_every:
        return None
    ring = self.ring
    nxt = self.succ(self.id)
    gap = []
    i = (self.id + 1) % 7
    while i != nxt and i != self.id:
        if i in cfg.team and i not in ring:
            gap.append(i)
        i = (i + 1) % 7
    if self.lone:
        gap = [r for r in sorted(cfg.team) if r != self.id]
        gap = [r for r in gap if r > self.id] + [r for r in gap if r < self.id]
    if not gap:
        self._turns_since_poll = 0     # nobody to invite: look again in poll_every turns
        return None
    k = self._poll_ptr.get(nxt, 0) % len(gap)
    self._poll_ptr[nxt] = k + 1
    self._turns_since_poll = 0
    return gap[k]


def _build_frame(self: RotationalMac, now: int, out: list) -> tuple[Frame, bytes]:
    """This turn's one frame: a message (or a heartbeat) plus acks and an invitation."""
    if self._paper:
        return self._paper_build(now, out)
    kind: int                               # a FrameType, or the Type announced
    if self._answering or (self._booting and self._announcing is None and
                           not self._lone_boot):
        # The answer to an invitation, or a lone claimer's first frame: nothing else in it.
        # A BOOT frame is Number '00'; a JOIN frame takes the next Number, so that its
        # acknowledgement cannot be mistaken for a message's (docs/protocol.md §4.4,
        # clause 34).
        self._answering = False
        self._sent_poll = None
        if self._booting:
            kind, num = FrameType.BOOT, 0
        else:
            kind, num = FrameType.JOIN, self._next_num
            self._next_num = (num + 1) % 100
        self._announcing, self._ann_num, self._ann_turns = kind, num, 1
        self._ann_awaiting = set(self.ring) - {self.id}
        if not self._ann_awaiting and kind == FrameType.BOOT:
            # A lone claimer's BOOT: nobody acknowledged it, so nobody forgot our old
            # Numbers. It stays unacknowledged (clause 34): the answer to the invitation
            # that brings us into a ring is BOOT, not JOIN, or a member that remembers
            # our last Number from before the restart takes our message with that Number
            # for a duplicate (found on the bench: a father restarted on a live ring).
            self._announcing = None
            self._lone_boot = True
        elif not self._ann_awaiting:
            self._announced()
        frame = self._frame(BROADCAST, num, kind, b"")
        return frame, frame.encode()
    if self._announcing is not None:
        # BOOT/JOIN frames until every member has acknowledged: a BOOT so that no message
        # of ours comes before every receiver forgot our old Numbers; a JOIN so that we
        # know every member heard us join (else we would share a slot with someone).
        self._ann_turns += 1
        self._expire(now, out)
        msg, poll_to = None, None
    else:
        msg = self._pick_message(now, out)
        poll_to = self._poll_target()
    crc_room = self._ext_len
    extra: list[Command] = []
    if poll_to is not None:
        extra.append(cmd("poll", poll_to, _mask(self.ring)))
    elif self._tell_view and self._announcing is None and not self.lone:
        extra.append(cmd("ring", _mask(self.ring)))
    acks = self._acks
    room = self.max_content - crc_room - (len(msg.content) if msg is not None else 0)
    if msg is not None and (acks and self._acks_deferred or room < 0 or
                            room < sum(_ack_len(a) for a in acks)):
        # Acknowledgements never wait behind a message: a sender that heard no ack by its
        # next turn retransmits its whole frame (up to Tmax of air). Our message goes
        # next turn instead (docs/protocol.md §4.7).
        msg = None
        room = self.max_content - crc_room
    carried: list[Command] = []
    used = sum(len(c.text()) for c in extra) if extra else 0
    if used > room:
        extra, used, poll_to = [], 0, None
    elif extra:
        self._tell_view = False            # a poll's mask tells our view too
    kept = []
    for a in acks:
        n = _ack_len(a)
        if used + n <= room:
            carried.append(cmd("ack", a[0], a[1]))
            used += n
        else:
            kept.append(a)
    self._acks = kept
    self._acks_deferred = bool(kept)
    self._sent_poll = poll_to
    mac_part = carried + extra
    if msg is not None:
        msg.attempts += 1
        msg.state = "sent"
        self._last_num = msg.num           # control frames repeat it from now on
        content = msg.content + (format_content(mac_part) if mac_part else b"")
        frame = self._frame(msg.dst, msg.num, msg.type, content)
        return frame, frame.encode()
    num = self._last_num
    content = format_content(mac_part) if mac_part else b""
    kind = FrameType.BROADCAST_INFO
    if self._announcing is not None:
        kind, num = self._announcing, self._ann_num
    if self._key is not None:           # every frame differs: its own freshness
        frame = self._frame(BROADCAST, num, kind, content)
        return frame, frame.encode()
    key = (num, content, kind)
    hit = self._hb_cache.get(key)
    if hit is None:
        frame = self._frame(BROADCAST, num, kind, content)
        hit = (frame, frame.encode())
        if len(self._hb_cache) < HB_CACHE_MAX:
            self._hb_cache[key] = hit
    return hit


def _frame(self: RotationalMac, dst: int, num: int, type: int, content: bytes) -> Frame:
    if self._key is not None:
        fresh = self.auth_tx
        self.auth_tx = fresh + 1
        self._auth_rx[self.id] = fresh     # a replay of our own frame is stale too
        return _auth.seal(self._key, dst, self.id, num, int(type), content, fresh)
    if self.cfg.checksum:
        return seal(dst, self.id, num, int(type), content)
    return Frame(dst=dst, src=self.id, num=num, type=type, content=content)
