"""The accounting of a simulated run, kept beside the firmware and never seen by it: each robot's
counts, every message submitted and how it ended, each delivery checked against what its sender
submitted (the ground truth the invariants of docs/guarantees.md are checked on: delivered
twice, to the wrong robot, corrupted), the membership changes, what the robots said of their
identity. The world (hil/sim/world.py) feeds it from the MACs' reports."""
from __future__ import annotations

from collections import Counter, deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from firmware_model.radio.frame import BROADCAST
from firmware_model.radio.mac import UNACKNOWLEDGED, Deliver, Message, Outcome
from firmware_model.timing import TICK_HZ

if TYPE_CHECKING:
    from .world import World

KEYED = 8
"""The latest messages kept per (Source, Number) to check a delivery against: Numbers wrap,
and the father's two PCs number their own queues."""

RETIRE_TICKS = 2 * TICK_HZ
"""How long after its outcome a message is still kept to check deliveries against (2 s,
ticks): more than a frame can last (Tmax, 600 ms), so whatever frame of it a robot delivers
has ended by then."""


@dataclass
class RobotStats:
    received: int = 0
    refused_frames: int = 0
    numbers_behind: int = 0
    bad_frames: int = 0
    duplicates: int = 0
    submitted: int = 0
    delivered: int = 0
    failed: int = 0
    unacknowledged: int = 0     # paper profile: sent once, nothing acknowledges it
    refused: int = 0
    missed: int = 0


class Tally:
    """The world's count of one bus's frames, kept in that child's CAN domain."""

    STEADY_COUNTERS = ("frames",)
    """The world's tally of a bus's frames: counts only (hil/sim/steady.py)."""

    __slots__ = ("frames",)

    def __init__(self) -> None:
        self.frames = 0


def spread(counts: Counter) -> dict:
    """count, min, median and max of the values ``counts`` holds (value -> how many; ticks):
    the median is the value at index count // 2 of them sorted."""
    n = sum(counts.values())
    half, seen = n // 2, 0
    median = None
    for v in sorted(counts):
        seen += counts[v]
        if seen > half:
            median = v
            break
    return {"count": n, "min": min(counts), "median": median, "max": max(counts)}


class SameHappening:
    """Tells the first report of a happening that every robot hearing the air reports on its
    own (a robot's missed turn, its drop, its join or rejoin) from the other observers'
    reports of it: those come within ``same_turn`` ticks of the first. Each observer times a
    turn from the same frame's End, but on the CPU model its timer's handler has its effects
    a few hundred cycles later on one CPU than on another (and the father's PC is another CPU
    again), so they need not come at one tick. Half of Tmax is the world's: a robot's next
    miss, or its next change of one kind, is at least a turn, Tmax, later. 0: only reports
    at the same tick are one."""

    __slots__ = ("same_turn", "_last")

    def __init__(self, same_turn: int = 0) -> None:
        self.same_turn = same_turn
        self._last: dict[tuple[str, int], int] = {}
        """(kind, robot) -> the tick of the happening last counted."""

    def first(self, kind: str, robot: int, now: int) -> bool:
        """Is this report of ``kind`` about ``robot`` at tick ``now`` the first of its
        happening, not another observer's of one counted within ``same_turn`` before?"""
        key = (kind, robot)
        last = self._last.get(key)
        if last is not None and now - last <= self.same_turn:
            return False
        self._last[key] = now
        return True


class Ledger:
    """The run's accounting for the robots of the ring ``robots``. ``keep``: keep every
    message submitted and every outcome (``messages``, ``outcomes``, ``deliveries`` whole);
    otherwise only what the summary and the invariants need: counts, histograms, and the
    messages a delivery may still be checked against (the open ones, and those ended less
    than :data:`RETIRE_TICKS` ago), so a day's run holds what an hour's does."""

    def __init__(self, robots, keep: bool = False, same_turn: int = 0) -> None:
        self.stats: dict[int, RobotStats] = {r: RobotStats() for r in robots}
        self.membership: list[tuple[int, str, int]] = []   # (tick, kind, robot), deduplicated
        self._reports = SameHappening(same_turn)
        """Which observers' reports of a miss, a drop, a join or a rejoin are one happening
        (``same_turn``: ticks, :class:`SameHappening`)."""
        self.keep = keep
        self.outcomes: list[Outcome] | None = [] if keep else None
        self.latency_ms: Counter = Counter()
        """Delivered messages by latency, ms from submission to the sender's last
        acknowledgement, rounded down: a histogram, bounded however long the run."""
        self.messages: list[Message] | None = [] if keep else None
        self.deliveries: Counter | None = Counter() if keep else None
        """(src, num, submit-serial, receiver) -> deliveries, kept whole with ``keep``."""
        self.submitted_count = 0
        self.ended_count = 0
        self.oldest_outcome = 0
        """The most ticks any message took from its submission to its outcome."""
        self.corrupt_deliveries = 0
        self.wrong_deliveries = 0
        self._by_key: dict[tuple[int, int], list[int]] = {}
        self._live: dict[int, Message] = {}
        """Serial -> message, for the messages a delivery may still be checked against."""
        self._received: dict[int, Counter] = {}
        """Serial -> receiver -> deliveries, for those messages."""
        self._retiring: deque[tuple[int, int]] = deque()    # (tick it ended, serial)
        self._serial_of: dict[Message, int] = {}
        """Message -> its serial, until it ends. Keyed by the message itself (a Message
        hashes by identity), never by ``id()``: a pickled world's copy (the stateful tests',
        hil/sim/lockstep.py's) would keep the original's ids, stale keys that a message of the
        copy may later share, so a message's end would retire another, still in flight, and
        its delivery after RETIRE_TICKS would count as corrupted."""
        self._duplicates_retired = 0
        self.identity: list[dict] = []
        """Every duplicate_id and foreign_ring said, by any robot (the summary lists them)."""

    def message(self, serial: int) -> Message | None:
        """The message submitted ``serial``-th (1 on), while it may still be delivered (any,
        with ``keep``)."""
        if self.messages is not None:
            return self.messages[serial - 1]
        return self._live.get(serial)

    @property
    def duplicate_deliveries(self) -> int:
        """Deliveries of a message to a robot that had delivered it already (docs/guarantees.md:
        never)."""
        return self._duplicates_retired + sum(
            c - 1 for per in self._received.values() for c in per.values() if c > 1)

    def _retire(self, now: int) -> None:
        """Forget the messages that ended more than :data:`RETIRE_TICKS` before ``now``: no
        frame of theirs can still be on the air (a frame lasts at most Tmax), so no robot can
        deliver them again; their duplicate deliveries become a count."""
        q = self._retiring
        while q and q[0][0] + RETIRE_TICKS < now:
            self._forget(q.popleft()[1])

    def _forget(self, serial: int) -> None:
        """Check no delivery against message ``serial`` any more; its duplicate deliveries
        become a count."""
        m = self._live.pop(serial, None)
        per = self._received.pop(serial, None)
        if per is not None:
            self._duplicates_retired += sum(c - 1 for c in per.values() if c > 1)
        if m is not None:
            key = (m.src, m.num)
            keyed = self._by_key.get(key)
            if keyed is not None and serial in keyed:
                keyed.remove(serial)
                if not keyed:
                    del self._by_key[key]

    def missed(self, now: int, robot: int) -> None:
        """``robot`` missed its turn, as one robot that hears the air saw it: counted once per
        turn however many saw it (:class:`SameHappening`)."""
        if self._reports.first("miss", robot, now) and robot in self.stats:
            self.stats[robot].missed += 1

    def membership_change(self, kind: str, robot: int, now: int, observed: bool = True
                          ) -> None:
        """A join, rejoin or disable that the robots hearing the air saw (``observed``: listed
        once however many saw it: :class:`SameHappening`), or a robot's own change of mode (not
        ``observed``: it alone says it, every one listed), at its first report's tick."""
        # a join and a rejoin of one robot at once are one admission: whether an observer
        # says "rejoin" depends on whether it ever had the robot in its ring
        key = "join" if kind == "rejoin" else kind
        if not observed or self._reports.first(key, robot, now):
            self.membership.append((now, kind, robot))

    def _serial(self, a: Deliver) -> int:
        """The serial (1 on) of the latest message submitted that ``a`` delivers whole, 0 if
        none: a delivery the sender's message does not match is corrupted."""
        for cand in reversed(self._by_key.get((a.src, a.num), ())):
            m = self.message(cand)
            if m is not None and m.dst == a.dst and m.type == a.type and \
                    m.commands == a.commands:
                return cand
        return 0

    def delivered_to(self, a: Deliver, r: int) -> bool:
        """Robot ``r`` of the ring delivered ``a`` to its application: counted, checked against
        the ground truth the firmware cannot see; True if it is what the sender submitted."""
        self.stats[r].received += 1
        serial = self._serial(a)
        intact = serial != 0
        if intact:
            per = self._received.get(serial)
            if per is None:
                per = self._received[serial] = Counter()
            per[r] += 1
            if self.deliveries is not None:
                self.deliveries[(a.src, a.num, serial, r)] += 1
        else:
            self.corrupt_deliveries += 1
        if a.dst not in (r, BROADCAST):
            self.wrong_deliveries += 1
        return intact

    def intact(self, a: Deliver) -> bool:
        """Whether ``a`` is what its sender submitted, counted nowhere (a robot outside the
        ring delivered it)."""
        return self._serial(a) != 0

    def ended(self, a: Outcome, now: int) -> str:
        """A message's outcome at its sender at tick ``now``: ``delivered``, ``sent`` (the
        paper profile: sent once, unacknowledged) or ``fail``."""
        m = a.message
        self.ended_count += 1
        if now - m.submitted > self.oldest_outcome:
            self.oldest_outcome = now - m.submitted
        if self.outcomes is not None:
            self.outcomes.append(a)
        serial = self._serial_of.pop(m, None)
        if serial is not None:
            self._retiring.append((now, serial))
        s = self.stats[m.src]
        if a.delivered:
            s.delivered += 1
            self.latency_ms[(now - m.submitted) * 1000 // TICK_HZ] += 1
            return "delivered"
        if m.state == UNACKNOWLEDGED:
            s.unacknowledged += 1
            return "sent"
        s.failed += 1
        return "fail"

    def submitted(self, a: Message) -> None:
        """A message was queued at its sender."""
        self._retire(a.submitted)
        self.stats[a.src].submitted += 1
        self.submitted_count += 1
        serial = self.submitted_count
        if self.messages is not None:
            self.messages.append(a)
        self._live[serial] = a
        self._serial_of[a] = serial
        keyed = self._by_key.setdefault((a.src, a.num), [])
        keyed.append(serial)
        if len(keyed) > KEYED:
            self._forget(keyed[0])          # never matched again


def summary(world: World) -> dict:
    """The figures of the paper's simulator (Fig. 9) and the delivery accounting of
    ``world``'s run so far (``World.summary``)."""
    world.wake_can()
    robots: dict[int, dict[str, Any]] = {}
    for r in sorted(world.stations):
        st, s = world.stations[r], world.stats[r]
        pending = st.mac.pending + (world.standby_station.mac.pending
                                    if r == 0 and world.standby_station else 0)
        robots[r] = {"frames_sent": world.air.sent.get(r, 0), "received": s.received,
                     "pending": pending, "missed": s.missed,
                     "submitted": s.submitted, "delivered": s.delivered,
                     "failed": s.failed, "unacknowledged": s.unacknowledged,
                     "refused": s.refused,
                     "duplicates_dropped": s.duplicates, "refused_frames":
                     s.refused_frames, "refused_by": dict(sorted(st.refused.items())),
                     "numbers_behind": s.numbers_behind,
                     "bad_frames": s.bad_frames, "mode": st.mac.mode,
                     "ring": list(st.mac.ring)}
    total = lambda k: sum(v[k] for v in robots.values())  # noqa: E731
    dup_deliveries = world.ledger.duplicate_deliveries
    return {"duration_ticks": world.sched.now, "robots": robots,
            "occupations": world.air.occupations, "collisions": world.collisions,
            "membership_changes": [{"t": t, "ev": k, "robot": r}
                                   for t, k, r in world.membership],
            "submitted": total("submitted"), "delivered": total("delivered"),
            "failed": total("failed"), "unacknowledged": total("unacknowledged"),
            "pending": total("pending"),
            "can_frames": world.can_frames,
            **({"identity": world.identity} if world.identity else {}),
            **({"cpu_load": {r: round(c.load(), 6) for r, c in sorted(world.cpus.items())},
                "cpu_overruns": {r: world.stations[r].uart.overruns
                                 for r in sorted(world.cpus)},
                "cpu_tx_gaps": {r: world.stations[r].uart.gaps
                                for r in sorted(world.cpus)}} if world.cpus else {}),
            **({"dispatch_latency_ticks": spread(world.dispatch_latency_ticks)}
               if world.dispatch_latency_ticks else {}),
            "duplicate_deliveries": dup_deliveries,
            "oldest_outcome_s": round(world.ledger.oldest_outcome / TICK_HZ, 3),
            "corrupt_deliveries": world.ledger.corrupt_deliveries,
            "wrong_robot_deliveries": world.ledger.wrong_deliveries}
