"""Peer (contention) MACs a user may pick instead of the rotational TDMA MAC (docs/peer-macs.md).

Three classic random-access MACs on the same half-duplex PTR2000 channel, each with the method
surface of :class:`~firmware_model.radio.mac.RotationalMac` (``power_on``, ``on_frame``,
``on_corrupt``, ``on_garbage``, ``on_timer``, ``on_tx_done``, ``submit``, ``deadline``, ``mode``,
``ring``, ``pending``, ``max_content``, ``cfg``) so a :class:`~firmware_model.station.RadioStation`
drives them unchanged, and with the same delivery accounting (``ack(src,num)``, bounded
retries, one :class:`Outcome` per submitted message, duplicates dropped by (Source, Number)):

* :class:`AlohaMac` (``"aloha"``, pure ALOHA): a frame is sent as soon as one is ready (TXEN at
  once, the frame Ttrans later). No ack within the ack wait: retransmit after a uniform random
  backoff. Nothing to say, nothing sent (no heartbeats).
* :class:`SlottedAlohaMac` (``"slotted"``): the same, but every frame starts on a slot
  boundary ``k x slot`` counted from tick 0 by every robot (TXEN at the boundary - Ttrans);
  ``slot = frame_bytes x 16667 + Ttrans + guard`` unless configured.
* :class:`CsmaMac` (``"csma"``, non-persistent CSMA): before a data frame, sense the channel
  from the bytes heard (the PTR2000 has no carrier detect): a byte heard within the last
  ``sense_bytes`` byte times (or a frame being received, or our own radio still deaf, or the
  ack guard after a unicast frame) means busy; busy: wait a uniform random time and sense
  again; idle: TXEN, frame Ttrans later. That Ttrans plus the one byte time before a frame's
  first byte is heard is the vulnerable window (the "propagation delay" of CSMA theory).

Delivery (all three): a receiver acknowledges every data frame for it (or broadcast) with
``ack(src,num)`` in its next frame, which it sends at once (slotted: in the next slot) as a
short frame of its own, or piggybacked on a data frame that is ready then and still fits in
``frame_bytes``. Broadcast receivers stagger their acks by rank (ID order) so they do not
collide with each other. A sender keeps up to ``window`` messages awaiting acks; each is sent
at most ``max_attempts`` times within ``lifetime`` ticks of its first transmission, then ends as
failed with a reason. Receivers drop a copy of (Source, Number) heard within ``dup_window``; a
sender never reuses a Number within that window (docs/peer-macs.md gives the argument).

Every random draw comes from ``random.Random(f"{seed}:{kind}:{robot}")``.

Over 500 lines on purpose: three peer MACs (ALOHA, slotted ALOHA, CSMA) and the base they
share, kept together so they are compared on equal terms.
"""
from __future__ import annotations

import random
from typing import Iterable

from ..timing import FRAME_OVERHEAD, PC_BYTE_TICKS, max_content_bytes
from .content import Command, cmd, format_content
from .errors import ContentError
from .frame import BROADCAST, Frame, FrameType
from .integrity import CRC_TEXT_LEN, check as crc_ok, seal, strip as strip_crc
from .mac import (
    MEMBER, LISTEN, BadChecksum, BadContent, Deliver, Duplicate, MacConfig, Message, ModeChange,
    Outcome, QueueFull, Refused, RotationalMac, SubmitError, TX_OFF, TX_ON, Transmit, _layers,
    check_submission,
)
from .peer_config import (
    _GUARD_TICKS, _LATE_TICKS, MIN_FRAME_BYTES, PeerConfig, default_slot,
)
from .station_mac import StationMac

__all__ = [
    "KINDS", "PeerConfig", "PeerMac", "AlohaMac", "SlottedAlohaMac", "CsmaMac", "make_mac",
    "install", "default_slot", "MIN_FRAME_BYTES",
]

KINDS = ("rotational", "aloha", "slotted", "csma")
"""Every MAC ``make_mac`` builds; the first is the paper's."""

RX = "rx"            # receiving (TXEN low)
SWITCH = "switch"    # TXEN high; the frame goes out at ``_tx_at``
SEND = "send"        # a frame is on air; ``on_tx_done`` ends it

class _Track:
    """Sender-side state of one message (kept beside the shared ``Message`` record)."""

    __slots__ = ("ready", "timeout", "first_tx")

    def __init__(self, ready: int) -> None:
        self.ready: int | None = ready     # may go on air from this tick (None: awaiting ack)
        self.timeout: int | None = None    # ack wait ends at this tick
        self.first_tx: int | None = None


class PeerMac:
    """Shared machinery of the peer MACs; subclasses decide *when* a frame may start."""

    kind = "peer"

    def __init__(self, robot_id: int, config: MacConfig | None = None,
                 peer: PeerConfig | None = None, seed: int | str = 0) -> None:
        if not 0 <= robot_id <= 6:
            raise ValueError(f"robot ID must be 0-6, got {robot_id}")
        self.id = robot_id
        self.cfg = cfg = config or MacConfig()
        self.peer = p = peer or PeerConfig()
        self.rng = random.Random(f"{seed}:{self.kind}:{robot_id}")
        self.max_content = max_content_bytes(cfg.byte_ticks, cfg.tmax)
        bt = max(cfg.byte_ticks, PC_BYTE_TICKS)
        self._bt = bt
        self.frame_ticks = p.frame_bytes * bt
        """The backoff unit: the longest frame of the load, on air."""
        self.slot = p.slot or default_slot(p.frame_bytes, cfg.ttrans)
        # Broadcast acks: receiver of rank r answers r staggers after the frame.
        self.stagger = cfg.ttrans + self.frame_ticks + 2 * bt
        others = len(cfg.team - {robot_id}) if cfg.team else 6
        self._ranks = max(1, others)
        unit = self.slot if self.kind == "slotted" else self.frame_ticks
        per_try = self._ack_wait(0) + int(p.backoff * unit) + cfg.ttrans + \
            self.frame_ticks + 2 * int(p.sense_backoff * self.frame_ticks)
        self.lifetime = p.lifetime or cfg.max_attempts * per_try + \
            self._ack_wait(BROADCAST) - self._ack_wait(0)
        """Most ticks from a message's first transmission to its last (then it fails)."""
        longest = (self.max_content + FRAME_OVERHEAD) * bt
        self.dup_window = self.lifetime + longest
        self._reuse_gap = self.dup_window + longest
        self.mode = LISTEN
        self.phase = RX
        self.deadline: int | None = None
        self.heard: set[int] = set()
        self._queue: list[Message] = []        # submitted, never sent
        self._out: list[Message] = []          # sent, awaiting acknowledgement
        self._track: dict[Message, _Track] = {}
        self._acks: list[tuple[int, int, int]] = []   # (ready tick, src, num) to send
        self._seen: dict[tuple[int, int], int] = {}   # (src, num) -> tick last heard
        self._num_tx: dict[int, int] = {}      # Number -> tick of its last transmission
        self._next_num = 0
        self._last_num = 0
        self._rx_from = 0                      # our radio hears again from this tick
        self._txen_at = 0
        self._tx_at = 0
        self._tx_start = 0
        self._sending: Message | None = None
        # Counters (benchmarks and traces).
        self.frames_sent = 0
        self.data_frames = 0
        self.ack_frames = 0
        self.sense_attempts = 0
        self.sense_busy = 0
        self.retransmissions = 0

    # -- queries ---------------------------------------------------------------------------

    @property
    def pending(self) -> int:
        """Messages submitted and not yet ended (queued or awaiting acknowledgement)."""
        return len(self._queue) + len(self._out)

    @property
    def ring(self) -> tuple[int, ...]:
        """The robots heard so far and this one (a peer MAC has no ring; for the world's
        summaries and the bench's "is the destination there" check)."""
        return tuple(sorted(self.heard | {self.id}))

    # -- events in ---------------------------------------------------------------------------

    def power_on(self, now: int) -> list:
        self.mode = MEMBER
        self.phase = RX
        self._rx_from = now
        self._arm(now)
        return [TX_OFF, ModeChange(MEMBER, f"{self.kind} MAC on")]

    def submit(self, dst: int, commands: Iterable[Command], now: int,
               type: int = FrameType.INSTRUCTION) -> Message:
        """Queue a message; raises SubmitError if it can never be sent."""
        commands, content = check_submission(self.id, dst, commands, type)
        crc = CRC_TEXT_LEN if self.cfg.checksum else 0
        limit = self.content_limit
        if len(content) > limit:
            raise SubmitError(
                f"Content of {len(content)} bytes makes a {len(content) + crc + FRAME_OVERHEAD}"
                f"-byte frame; the {self.kind} MAC sends at most {limit + crc + FRAME_OVERHEAD}"
                f"-byte frames{self._limit_why()}; split the message")
        if self.pending >= self.cfg.max_queue:
            raise QueueFull(f"queue full ({self.cfg.max_queue} messages pending)")
        msg = Message(self.id, dst, self._next_num, int(type), commands, content, now)
        self._last_num = self._next_num
        self._next_num = (self._next_num + 1) % 100
        last = self._num_tx.get(msg.num)
        self._track[msg] = _Track(now if last is None else max(now, last + self._reuse_gap))
        self._queue.append(msg)
        self._arm(now)
        return msg

    def _content_limit(self) -> int:
        return self.max_content

    @property
    def content_limit(self) -> int:
        """The longest Content of a message this MAC takes (bytes; a slotted frame fits its
        slot, its crc() counted)."""
        return self._content_limit() - (CRC_TEXT_LEN if self.cfg.checksum else 0)

    def _limit_why(self) -> str:
        return " (Tmax)"

    def on_frame(self, frame: Frame, first: int, end: int, now: int) -> list:
        """A valid frame was heard (its End completed at ``end``)."""
        out: list = []
        src = frame.src
        if src == self.id or src not in self.cfg.team:
            # Our own ID from the air (we are deaf while sending), or a robot outside the
            # team: never acted on.
            out.append(Refused(src, frame.num, "our own robot ID from the air"
                               if src == self.id else f"robot {src} is not in the team"))
            return out
        content = frame.content
        if self.cfg.checksum:
            if not crc_ok(frame):
                out.append(BadChecksum(first, end))
                return out
            content = strip_crc(content)
        self.heard.add(src)
        try:
            mac_cmds, app_cmds = _layers(content) if content else ((), ())
        except ContentError as exc:
            out.append(BadContent(src, frame.num, exc))
            self._arm(now)
            return out
        for c in mac_cmds:
            if c.name == "ack" and c.args[0] == self.id:
                self._on_ack(src, c.args[1], out)
        if app_cmds:
            if frame.dst == self.id or frame.dst == BROADCAST:
                ready = self._ack_ready(frame, end)
                key = (src, frame.num)
                if not any(a[1] == src and a[2] == frame.num for a in self._acks):
                    self._acks.append((ready, src, frame.num))
                last = self._seen.get(key)
                self._seen[key] = end
                if last is not None and end - last <= self.dup_window:
                    out.append(Duplicate(src, frame.num))
                else:
                    out.append(Deliver(src, frame.dst, frame.num, frame.type, app_cmds))
            if frame.dst != self.id:
                self._overheard(frame, end)
        self._arm(now)
        return out

    def on_corrupt(self, first: int, src: int | None, expected_end: int | None,
                   now: int) -> list:
        """A frame broke after its Header (a collision, mostly): its sender will time out."""
        self._arm(now)
        return []

    def on_garbage(self, first: int, last: int, now: int) -> list:
        return []

    def on_frame_over(self, now: int) -> list:
        """A failed frame's bytes stopped before the End it promised: nothing to do (a peer MAC
        keeps no turn that the promised End would close)."""
        return []

    def on_timer(self, now: int, rx_busy: bool = False, last_rx: int | None = None,
                 rx_began: int | None = None) -> list:
        out: list = []
        if self.mode != MEMBER:
            return out
        self._expire(now, out)
        if self.phase == SWITCH:
            if now >= self._tx_at:
                self._send(now, out)
        elif self.phase == RX:
            self._maybe_start(now, rx_busy, last_rx, out)
        self._arm(now)
        return out

    def on_tx_done(self, now: int) -> list:
        """The last bit of our frame left: back to receive, start the ack wait."""
        out: list = [TX_OFF]
        self.frames_sent += 1
        self.phase = RX
        self._rx_from = now + self.cfg.ttrans
        m = self._sending
        self._sending = None
        if m is not None and m in self._track:
            self._track[m].timeout = self._tx_start + self._ack_wait(m.dst, now - self._tx_start)
        self._arm(now)
        return out

    def force_turn(self, now: int) -> list:
        """Fault injection of the rotational MAC; a peer MAC has no turn to steal."""
        return []

    def resync(self, now: int) -> list:
        """The station was not running for longer than the margins allow (a bench process
        stopped; ``RadioStation.resync``). A peer MAC keeps no view of the air but its
        timers, which run when the station next looks; like the rotational MAC it does not
        send a frame decided before the gap: TXEN raised for one goes down, and whatever was
        due (acks, data) is decided again from now. A frame already on the air ends first
        (the station resyncs after it)."""
        out: list = []
        if self.mode == MEMBER and self.phase == SWITCH:
            self.phase = RX
            self._rx_from = now + self.cfg.ttrans
            out.append(TX_OFF)
        self._arm(now)
        return out

    # -- delivery ----------------------------------------------------------------------------

    def _ack_ready(self, frame: Frame, end: int) -> int:
        """When our ack of this frame may go: at once, or after our broadcast rank."""
        if frame.dst != BROADCAST:
            return end
        rank = sorted(self.cfg.team - {frame.src}).index(self.id) \
            if self.id in self.cfg.team else 0
        return end + rank * self.stagger

    def _ack_wait(self, dst: int, air: int | None = None) -> int:
        """Ticks from our frame's first byte to the end of the ack wait."""
        air = self.frame_ticks if air is None else air
        n = self._ranks if dst == BROADCAST else 1
        return air + (n - 1) * self.stagger + self.cfg.ttrans + self.frame_ticks + \
            2 * self._bt + _GUARD_TICKS

    def _overheard(self, frame: Frame, end: int) -> None:
        """A data frame for another robot or for all (CSMA protects the acks it calls for)."""

    def _on_ack(self, src: int, num: int, out: list) -> None:
        for m in self._out:
            if m.num == num and src in m.awaiting:
                m.awaiting.discard(src)
                m.acked.add(src)
                if not m.awaiting:
                    self._finish(m, True, "", out)
                return

    def _finish(self, m: Message, delivered: bool, reason: str, out: list) -> None:
        m.state = "delivered" if delivered else "failed"
        m.reason = reason
        if m in self._out:
            self._out.remove(m)
        elif m in self._queue:
            self._queue.remove(m)
        self._track.pop(m, None)
        out.append(Outcome(m, delivered, reason))

    def _expire(self, now: int, out: list) -> None:
        """Ack waits that ran out: schedule the retransmission after a backoff, or fail."""
        cfg = self.cfg
        for m in list(self._out):
            tr = self._track[m]
            if tr.timeout is None or now < tr.timeout or m is self._sending:
                continue
            tr.timeout = None
            missing = ",".join(str(r) for r in sorted(m.awaiting))
            if m.attempts >= cfg.max_attempts:
                self._finish(m, False, f"no acknowledgement from {missing} after "
                             f"{m.attempts} attempts", out)
                continue
            tr.ready = now + self._backoff()
            assert tr.first_tx is not None            # it timed out: it was sent
            if tr.ready - tr.first_tx > self.lifetime:
                self._finish(m, False, f"expired: no acknowledgement from {missing} within "
                             f"{self.lifetime // 16_000} ms after {m.attempts} attempt(s)", out)
        for m in list(self._queue):
            if now - m.submitted > cfg.max_age:
                self._finish(m, False, f"expired: not sent within {cfg.max_age // 16_000} ms",
                             out)

    def _backoff(self) -> int:
        return int(self.rng.random() * self.peer.backoff * self.frame_ticks)

    # -- what is ready, and when ---------------------------------------------------------------

    def _ack_time(self) -> int | None:
        return min((a[0] for a in self._acks), default=None)

    def _data_time(self) -> int | None:
        """Earliest tick a data frame (retransmission or new message) may go."""
        t = None
        for m in self._out:
            r = self._track[m].ready
            if r is not None and (t is None or r < t):
                t = r
        if len(self._out) < self.peer.window and self._queue:
            r = self._track[self._queue[0]].ready
            assert r is not None                      # a queued message has its tick
            if t is None or r < t:
                t = r
        return t

    def _pick_data(self, by: int, now: int, out: list) -> Message | None:
        """The data message for a frame whose TXEN rose at ``by``: the most overdue
        retransmission, else the next new message (window permitting)."""
        best = None
        best_ready = 0
        for m in list(self._out):
            tr = self._track[m]
            if tr.ready is None or tr.ready > by:
                continue
            assert tr.first_tx is not None            # in _out: it was sent
            if now - tr.first_tx > self.lifetime:
                self._finish(m, False, f"expired: no acknowledgement from "
                             f"{','.join(str(r) for r in sorted(m.awaiting))} within "
                             f"{self.lifetime // 16_000} ms after {m.attempts} attempt(s)", out)
                continue
            if best is None or tr.ready < best_ready:
                best, best_ready = m, tr.ready
        if best is not None:
            return best
        if len(self._out) < self.peer.window and self._queue:
            m = self._queue[0]
            ready = self._track[m].ready
            assert ready is not None                  # a queued message has its tick
            if ready <= by:
                return m
        return None

    def _arm(self, now: int) -> None:
        """Set ``deadline``: the next tick anything is due (a TX start, the frame after
        Ttrans, an ack wait's end)."""
        if self.mode != MEMBER:
            self.deadline = None
            return
        cands = [tr.timeout for tr in self._track.values() if tr.timeout is not None]
        if self.phase == SWITCH:
            cands.append(self._tx_at)
        elif self.phase == RX:
            t = self._start_time(now)
            if t is not None:
                cands.append(t)
        if self._queue:
            cands.append(self._queue[0].submitted + self.cfg.max_age + 1)
        self.deadline = max(now, min(cands)) if cands else None

    # -- the policy: subclasses --------------------------------------------------------------

    def _start_time(self, now: int) -> int | None:
        """Tick to raise TXEN (or, CSMA, to sense) next, or None (nothing to send)."""
        a, d = self._ack_time(), self._data_time()
        if a is None:
            return d
        return a if d is None else min(a, d)

    def _maybe_start(self, now: int, rx_busy: bool, last_rx: int | None, out: list) -> None:
        t = self._start_time(now)
        if t is not None and t <= now:
            self._switch(now, out)

    # -- sending -------------------------------------------------------------------------------

    def _switch(self, now: int, out: list, tx_at: int | None = None) -> None:
        self.phase = SWITCH
        self._txen_at = now
        self._tx_at = now + self.cfg.ttrans if tx_at is None else tx_at
        out.append(TX_ON)

    def _frame_room(self) -> int:
        """Bytes a frame may have (``frame_bytes``; a lone data frame may be longer)."""
        return self.peer.frame_bytes

    def _send(self, now: int, out: list) -> None:
        """Build the one frame: due acks first, then a data message if it fits."""
        by = self._txen_at
        crc = CRC_TEXT_LEN if self.cfg.checksum else 0
        room = self._frame_room() - FRAME_OVERHEAD - crc
        acks = sorted(a for a in self._acks if a[0] <= by)
        carried: list[tuple[int, int, int]] = []
        used = 0
        for a in acks:
            n = len(cmd("ack", a[1], a[2]).text())
            if used + n > room:
                break
            carried.append(a)
            used += n
        msg = self._pick_data(by, now, out)
        if msg is not None and carried and used + len(msg.content) > room:
            msg = None                        # the acks go now, the data in a later frame
        if msg is None and not carried:
            self.phase = RX                   # nothing left to say (acked meanwhile)
            self._rx_from = now + self.cfg.ttrans
            out.append(TX_OFF)
            return
        for a in carried:
            self._acks.remove(a)
        ack_text = format_content([cmd("ack", a[1], a[2]) for a in carried])
        if msg is not None:
            tr = self._track[msg]
            if msg in self._queue:
                self._queue.remove(msg)
                self._out.append(msg)
                msg.awaiting = {msg.dst} if msg.dst != BROADCAST else \
                    set(self.cfg.team) - {self.id}
                tr.first_tx = now
            else:
                self.retransmissions += 1
            tr.ready = None
            tr.timeout = None
            msg.attempts += 1
            msg.state = "sent"
            self._num_tx[msg.num] = now
            self.data_frames += 1
            frame = self._frame(msg.dst, msg.num, msg.type, msg.content + ack_text)
        else:
            dsts = {a[1] for a in carried}
            dst = dsts.pop() if len(dsts) == 1 else BROADCAST
            self.ack_frames += 1
            frame = self._frame(dst, self._last_num, FrameType.BROADCAST_INFO, ack_text)
        self._sending = msg
        self._tx_start = now
        self.phase = SEND
        out.append(Transmit(frame, frame.encode()))

    def _frame(self, dst: int, num: int, type: int, content: bytes) -> Frame:
        if self.cfg.checksum:
            return seal(dst, self.id, num, int(type), content)
        return Frame(dst=dst, src=self.id, num=num, type=type, content=content)


class AlohaMac(PeerMac):
    """Pure ALOHA: TXEN as soon as a frame is ready; the frame goes Ttrans later."""

    kind = "aloha"


class SlottedAlohaMac(PeerMac):
    """Slotted ALOHA: frames start only at ``k x slot`` (every robot counts from tick 0).

    The timer is armed for a slot's TXEN tick (its boundary less Ttrans). A handler that
    comes late for it (the MB90F549 model takes a timer interrupt about 300 ticks after it
    is due) still sends in that slot, TXEN now and the frame Ttrans later, when it is at
    most :data:`_LATE_TICKS` late: taken for the next slot instead, every try came as late
    and no frame ever went (``--mac slotted`` on the CPU model sent nothing)."""

    kind = "slotted"
    _armed: int | None = None
    """The slot TXEN tick the timer was last armed for (:meth:`_arm`), or None."""

    def _arm(self, now: int) -> None:
        super()._arm(now)
        self._armed = self._start_time(now) if self.mode == MEMBER and self.phase == RX \
            else None

    def _boundary(self, t: int) -> int:
        """First slot boundary b with b - Ttrans >= t."""
        s = self.slot
        return -(-(t + self.cfg.ttrans) // s) * s

    def _start_time(self, now: int) -> int | None:
        t = super()._start_time(now)
        if t is None:
            return None
        return self._boundary(max(t, now)) - self.cfg.ttrans

    def _maybe_start(self, now: int, rx_busy: bool, last_rx: int | None, out: list) -> None:
        t = PeerMac._start_time(self, now)
        if t is None:
            return
        # The reload timer may fire a tick late (it counts machine clock / 2): still this slot.
        b = self._boundary(max(t, now - _GUARD_TICKS))
        due = self._armed
        if due is not None and t <= due < b - self.cfg.ttrans and now - due <= _LATE_TICKS:
            b = due + self.cfg.ttrans         # a late handler: the slot it was armed for
        if b - self.cfg.ttrans <= now:
            self._switch(now, out, tx_at=max(b, now + self.cfg.ttrans))

    def _backoff(self) -> int:
        return self.rng.randrange(max(1, round(self.peer.backoff))) * self.slot

    def _ack_ready(self, frame: Frame, end: int) -> int:
        # Unicast: the next slot; broadcast: rank slots later.
        if frame.dst != BROADCAST or self.id not in self.cfg.team:
            return end
        rank = sorted(self.cfg.team - {frame.src}).index(self.id)
        return end + rank * self.slot

    def _ack_wait(self, dst: int, air: int | None = None) -> int:
        n = self._ranks if dst == BROADCAST else 1
        return (1 + n) * self.slot - self.cfg.ttrans + _GUARD_TICKS

    def _frame_room(self) -> int:
        return (self.slot - self.cfg.ttrans - _GUARD_TICKS) // self._bt

    def _content_limit(self) -> int:
        return min(self.max_content, self._frame_room() - FRAME_OVERHEAD)

    def _limit_why(self) -> str:
        return f" (one slot of {self.slot} ticks)"


class CsmaMac(PeerMac):
    """Non-persistent CSMA, sensing from the bytes heard (the PTR2000 has no carrier detect)."""

    kind = "csma"

    def __init__(self, *a, **k) -> None:
        super().__init__(*a, **k)
        self._sense_at = 0          # busy last time: do not sense again before this tick
        self._guard_until = 0       # ack guard after a data frame for someone else

    def _start_time(self, now: int) -> int | None:
        a, d = self._ack_time(), self._data_time()
        if d is not None:
            d = max(d, self._sense_at)
        if a is None:
            return d
        return a if d is None else min(a, d)

    def busy(self, now: int, rx_busy: bool, last_rx: int | None) -> bool:
        """The carrier sense the firmware can do: our radio deaf (still switching back), the
        ack guard, a frame being received, or (``sense="bytes"``) any byte heard within
        ``sense_bytes`` byte times."""
        if now < self._rx_from or now < self._guard_until or rx_busy:
            return True
        if self.peer.sense == "frame":
            return False
        return last_rx is not None and now - last_rx < self.peer.sense_bytes * self._bt

    def _maybe_start(self, now: int, rx_busy: bool, last_rx: int | None, out: list) -> None:
        a = self._ack_time()
        if a is not None and a <= now:
            # Acks go at once without sensing: the frame they answer just held the channel,
            # and the other stations' ack guard keeps it for us.
            self._switch(now, out)
            return
        d = self._data_time()
        if d is None or max(d, self._sense_at) > now:
            return
        deaf = now < self._rx_from
        if not deaf:                # (our own radio switching back: no channel observation)
            self.sense_attempts += 1
        if deaf or self.busy(now, rx_busy, last_rx):
            self.sense_busy += not deaf
            wait = 1 + int(self.rng.random() * self.peer.sense_backoff * self.frame_ticks)
            self._sense_at = now + wait
            return
        self._switch(now, out)

    def _overheard(self, frame: Frame, end: int) -> None:
        if self.peer.ack_guard:
            self._guard(frame.src, frame.dst, end)

    def _guard(self, src: int, dst: int, end: int) -> None:
        """Busy until the acks a data frame (src -> dst, End at ``end``) calls for can have
        started: Ttrans + 2 bytes after it, after the last broadcast rank for a broadcast."""
        n = len(self.cfg.team - {src}) if dst == BROADCAST else 1
        until = end + (n - 1) * self.stagger + self.cfg.ttrans + 2 * self._bt
        self._guard_until = max(self._guard_until, until)

    def on_tx_done(self, now: int) -> list:
        m = self._sending
        if m is not None and self.peer.ack_guard:
            self._guard(self.id, m.dst, now)     # our own frame's acks are coming
        return super().on_tx_done(now)


_CLASSES = {"aloha": AlohaMac, "slotted": SlottedAlohaMac, "csma": CsmaMac}


def make_mac(kind: str, robot_id: int, config: MacConfig | None = None, seed: int | str = 0,
             peer: PeerConfig | None = None) -> StationMac:
    """The MAC a station runs: ``"rotational"`` (the paper's), ``"aloha"``, ``"slotted"`` or
    ``"csma"``. ``seed`` seeds the peer MACs' random draws (per kind and robot)."""
    if kind == "rotational":
        return RotationalMac(robot_id, config)
    try:
        cls = _CLASSES[kind]
    except KeyError:
        raise ValueError(f"unknown MAC {kind!r}; one of {', '.join(KINDS)}") from None
    return cls(robot_id, config, peer, seed)


def install(world, kind: str, peer: PeerConfig | None = None) -> dict[int, StationMac]:
    """Swap every station of a freshly built ``hil.sim.world.World`` (not yet run) to ``kind``.

    Each station keeps its own ``MacConfig`` (byte rate, team); the world powers the MACs on
    at their power-on ticks as usual. Returns the MACs by robot ID."""
    if world.sched.now != 0 or getattr(world, "standby_station", None) is not None:
        raise ValueError("install peer MACs on a fresh world without a standby father PC")
    macs: dict[int, StationMac] = {}
    for r, st in world.stations.items():
        mac = make_mac(kind, r, st.mac.cfg, seed=world.cfg.seed, peer=peer)
        st.mac = mac
        macs[r] = mac
    return macs
