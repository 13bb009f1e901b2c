"""The central planning module's dispatcher (paper Fig. 4, §V.B): radio commands in, CAN out.

Sans-IO like the MAC: ``on_message`` (a Content message the MAC delivered), ``on_can`` (a frame
the CAN controller received) and ``on_timer`` go in; CAN frames to send (``take_can()``),
radio messages to submit (``take_radio()``) and one ``deadline`` (tick) come out. The radio turn
and the CAN work are asynchronous: a move that takes seconds is a *job* that waits for the
submodules' done events while the ring keeps turning (paper §V.B: the action cycle and the
communication cycle are independent).

Failure information goes back to the requester as a Type '4' frame whose Content is
``fail(code)`` followed by the command that failed. Codes (docs/dispatcher.md):

====  =========================================================
1     target out of the arm's reach
2     target needs a joint outside its limits
3     parameter out of range (wheel speed, paw, joint number)
10+n  submodule n reported a fault (stalled, limit, overcurrent)
20+n  submodule n refused the command
30+n  submodule n did not respond (no done in time, or silent)
40    the CAN controller went bus-off
41    the CAN bus is blocked (stuck dominant): the child isolated itself
====  =========================================================

Submodule numbers: joints 1-4, wheel 5, paw 6 (docs/can.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Callable

from can_bus import dbc
from can_bus.frames import CanFrame

from .kinematics import (
    HOME, JOINT_LIMITS, WHEEL_MAX_SPEED, Pose, Unreachable, forward, inverse,
)
from .radio.content import Command, cmd
from .radio.frame import BROADCAST, FrameType
from .timing import TICK_HZ

WHEEL, PAW = 5, 6
RATED_SPEED = {i: float(dbc.signal_range(f"JOINT{i}_CMD", "speed")[1]) for i in range(1, 5)}
"""deg/s the dispatcher plans joint motion with: each joint's rated speed (rprs.dbc)."""

MARGIN = TICK_HZ // 2
"""Extra time (0.5 s) a submodule gets beyond the planned motion time to report done."""

_MOVING = 1
"""A joint status frame's ``state`` while it moves (rprs.dbc: 0 idle, 1 moving, 2 holding)."""
_HOLDING = 2
"""... and once it has arrived where its last command (the frame's ``seq``) sent it."""

ARRIVED_DEG = 0.05
"""A joint that reports an angle this close to where it was sent (deg) is there: a move to
it is a move to where the arm already is (status frames give 0.01 deg)."""

SILENCE = 3 * TICK_HZ // 10
"""A node whose status frames (every 100 ms) stop for 300 ms is not responding."""

PAW_STROKE = TICK_HZ  # 1 s: planning bound for a paw stroke (the node takes 0.8 s)
WHEEL_SETTLE = 6 * TICK_HZ // 5
"""1.2 s: the longest the wheel takes to reach a commanded speed (-300 to 300 mm/s at
500 mm/s^2)."""

ACTIONS: dict[int, tuple[float, float, float, float]] = {
    0: HOME,
    1: (90.0, 45.0, -90.0, 45.0),    # end link turned to the left (paper Fig. 11 (a))
    2: (-90.0, 45.0, -90.0, 45.0),   # end link turned to the right
}
"""Preset poses of ``act(n, ...)``: joint angles in degrees."""

CODE_RANGE = 3
CODE_FAULT = 10
CODE_REFUSED = 20
CODE_SILENT = 30
CODE_BUS_OFF = 40
CODE_BLOCKED = 41
_MOVES = frozenset({"movex", "movey", "movez", "moveto"})
REQUEST_TYPES = frozenset({int(FrameType.SEEK_HELP), int(FrameType.INVITATION),
                           int(FrameType.INSTRUCTION)})
"""Types '0'-'2': messages that ask something of their destination (docs/protocol.md §3);
'3' and '4' are information."""


@lru_cache(maxsize=1024)
def _pose(q: tuple[float, float, float, float]) -> Pose:
    """:func:`~firmware_model.kinematics.forward`, remembered: relative orders are planned
    from the commanded pose, which changes only when an order is accepted."""
    return forward(q)


@lru_cache(maxsize=4096, typed=True)
def _reach(x: float, y: float, z: float,
           phi: float) -> tuple[tuple[float, float, float, float] | None, int, str]:
    """(joint angles, 0, '') or (None, failure code, reason): :func:`~firmware_model.kinematics.
    inverse`, remembered (pure; the same order from the same pose is planned once, in the
    simulation; the CPU model still charges every plan its cycles)."""
    try:
        return inverse(x, y, z, phi), 0, ""
    except Unreachable as exc:
        return None, exc.code, str(exc)


CODE_NO_CAN = 42
"""The child has no CAN side at all (a radio-only ``rprs child``): it cannot act on orders."""


@dataclass(eq=False)
class Job:
    """Work in progress on the submodules for one command from ``requester``."""

    requester: int
    command: Command
    waiting: dict[int, int]              # node -> seq whose done we wait for
    deadline: int
    notice: int | None = None            # act(n): broadcast act(n,1) when done
    started: int = 0


@dataclass
class NodeView:
    """What the MCU knows of one submodule from its status frames."""

    seq: int = 0
    state: int = 0
    value: float = 0.0                   # angle (deg), speed (mm/s) or opening (%)
    last_seen: int | None = None
    extra: dict = field(default_factory=dict)
    status_at: int | None = None
    """Tick of its last status frame (``last_seen`` counts its events too, which carry no
    ``value``, ``state`` or ``seq``)."""


class Dispatcher:
    """Turns Content commands into CAN commands and submodule reports into radio replies."""

    STEADY_COUNTERS = ("replies_dropped",)
    """Counts only (hil/sim/steady.py)."""

    STEADY_RECORDS = ("log",)
    """What it noticed, in words: appended to, never read by the model (tests and the monitor
    read it; hil/sim/steady.py)."""

    LOG_KEEP = 1024
    """The log keeps its latest entries, between this many and twice as many: a tail for a
    person or a test to read, not a record that grows with a day's run."""

    def _note(self, entry: tuple[int, str]) -> None:
        """Append ``entry`` (tick, words) to the log, dropping its oldest half when full."""
        log = self.log
        log.append(entry)
        if len(log) >= 2 * self.LOG_KEEP:
            del log[:self.LOG_KEEP]

    def __init__(self, robot_id: int) -> None:
        self.id = robot_id
        self.nodes = {n: NodeView() for n in range(1, 7)}
        self._seq = {n: 0 for n in range(1, 7)}     # last command sequence number per node
        self.target = list(HOME)             # commanded joint angles (deg)
        self._rebase: set[int] = set()
        """Joints whose commanded angle is to be their next status at rest (after a stop() or
        a bus fault, where they are is not where they were sent); a new command clears it."""
        self.jobs: list[Job] = []
        self._can: list[CanFrame] = []
        self._radio: list[tuple[int, tuple[Command, ...], int]] = []
        self.deadline: int | None = None
        self.isolated = False
        self.log: list[tuple[int, str]] = []
        self.replies_dropped = 0
        """Radio messages (replies, reports) dropped, the radio's queue full (``not_taken``)."""
        self.bad_frames = 0
        """CAN frames received that do not decode (a wrong length, a remote frame, an id the
        acceptance masks let in that no node sends): ignored, counted."""
        self.report_done = True    # a finished order is reported done() to its sender
        # a robot's act(n,1) notice heard: (src, action, now)
        self.on_notice: Callable[[int, int, int], None] | None = None
        # our own action starts or ends: (action, phase, now)
        self.on_action: Callable[[int, str, int], None] | None = None

    # -- outputs -------------------------------------------------------------------------

    def take_can(self) -> list[CanFrame]:
        out, self._can = self._can, []
        return out

    def take_radio(self) -> list[tuple[int, tuple[Command, ...], int]]:
        out, self._radio = self._radio, []
        return out

    def not_taken(self, radio: list[tuple[int, tuple[Command, ...], int]], now: int) -> None:
        """Messages ``take_radio`` gave that the radio could not take (its queue full: it
        drains only in turns): dropped, counted (``replies_dropped``) and noted in the log,
        so that a robot flooded with orders faster than its turns carry the answers says so.
        (Held for later, they would keep a flooded child's CAN side awake for good.)"""
        n = len(radio)
        self.replies_dropped += n
        self._note((now, f"{n} repl{'y' if n == 1 else 'ies'} dropped: the radio's queue is "
                         f"full"))

    def has_output(self) -> bool:
        """Are CAN frames or radio messages waiting for ``take_can`` / ``take_radio``?"""
        return bool(self._can or self._radio)

    # -- inputs --------------------------------------------------------------------------

    def on_message(self, src: int, dst: int, commands: tuple[Command, ...], now: int,
                   type_: int = int(FrameType.INSTRUCTION)) -> None:
        """A message the radio delivered (once). Only a request (Types '0'-'2') is an order;
        information (a reply, a ``done()`` or ``fail()`` notice with the order it is about,
        a broadcast ``act``) is noted, never acted on: a notice quoting ``movex(8)`` must not
        move this arm (two robots would bounce the order and its notice for ever)."""
        request = type_ in REQUEST_TYPES
        for c in commands:
            if not request or (dst == BROADCAST and c.name in ("act", "fail")):
                if c.name in ("act", "fail", "done"):
                    self._note((now, f"robot {src}: {c.text()}"))
                    if c.name == "act" and c.args[1] == 1 and self.on_notice is not None:
                        self.on_notice(src, int(c.args[0]), now)
                if not request and c.name in ("done", "fail"):
                    break                        # what follows is the order it is about
                continue
            handler = getattr(self, f"_cmd_{c.name}", None)
            if handler is not None:
                handler(src, c, now)
        self._update_deadline()

    def on_can(self, frame: CanFrame, now: int) -> None:
        try:
            name, sig = dbc.decode(frame)
        except dbc.DbcError:
            self.bad_frames += 1
            return
        role = _ROLES.get(name)
        if role is None:
            pass
        elif role[0] == _STATUS:
            n = role[1]
            v = self.nodes[n]
            v.last_seen = v.status_at = now
            v.state = int(sig["state"])
            v.seq = int(sig["seq"])
            key = role[2]
            v.value = float(sig[key]) if key is not None else 0.0
            v.extra = sig
            if n in self._rebase and v.state != _MOVING:
                # the joint's first status at rest after a stop or a bus fault: the pose
                # relative orders are planned from (a movey(0) after stop() moved the tip
                # 10.7 mm, back to the last report before the stop)
                self._rebase.discard(n)
                lo, hi = JOINT_LIMITS[n]
                self.target[n - 1] = min(max(round(v.value, 2), lo), hi)
            if v.state == _HOLDING and n <= 4 and self.jobs:
                # a joint holding after our command with this seq has arrived: its done
                # event may have been lost (a software bus that dropped frames while a
                # bench process stalled), and an order it carried out would fail fail(3n)
                for job in list(self.jobs):
                    if job.waiting.get(n) == v.seq:
                        del job.waiting[n]
                        if not job.waiting:
                            self._job_done(job, now)
        else:
            n = role[1]
            self.nodes[n].last_seen = now
            kind, seq, code = int(sig["kind"]), int(sig["seq"]), int(sig["code"])
            for job in list(self.jobs):
                if job.waiting.get(n) != seq:
                    continue
                if kind == 1:
                    del job.waiting[n]
                    if not job.waiting:
                        self._job_done(job, now)
                elif kind == 2:
                    self._job_failed(job, CODE_FAULT + n, now)
                else:
                    self._job_failed(job, CODE_REFUSED + n, now)
            if kind == 2:
                self._note((now, f"submodule {n} fault code {code}"))
        self._update_deadline()

    def on_stall(self, late: int) -> None:
        """The process did not run for ``late`` ticks (a bench host's stall): that time is
        nobody's silence. Every job's deadline and start, and when each submodule was last
        heard, move on by ``late``, so no order fails 30+n for the reports the stall kept
        from being read (they come in next)."""
        for job in self.jobs:
            job.deadline += late
            job.started += late
        for v in self.nodes.values():
            if v.last_seen is not None:
                v.last_seen += late
            if v.status_at is not None:
                v.status_at += late
        self._update_deadline()

    def on_timer(self, now: int) -> None:
        for job in list(self.jobs):
            late = [n for n in job.waiting if now >= job.deadline or (
                (seen := self.nodes[n].last_seen) is not None and now - seen >= SILENCE
                and now - job.started >= SILENCE)]
            if late:
                self._job_failed(job, CODE_SILENT + late[0], now)
        self._update_deadline()

    def on_bus_fault(self, code: int, now: int) -> None:
        """The CAN side is unusable (bus-off 40, blocked 41): every job fails with the code;
        with no job running the father (ID 0) is told."""
        if not self.jobs:
            self._fail(0, code, cmd("status"))
        for job in list(self.jobs):
            self._job_failed(job, code, now)
        self.isolated = code == CODE_BLOCKED
        self._rebase.update(range(1, 5))   # what was sent did not all go: ask the joints
        self._update_deadline()

    def on_bus_back(self, now: int) -> None:
        """The CAN driver left standby to try the bus again (it re-isolates, and reports
        fail(41) again, if the bus is still blocked): ``status()`` is answered again. It
        answered fail(41) for good after one blocked second."""
        self.isolated = False

    # -- commands (the Content command table's app layer) ----------------------------------

    def _cmd_movex(self, src: int, c: Command, now: int) -> None:
        self._move(src, c, now)

    _cmd_movey = _cmd_movez = _cmd_moveto = _cmd_movex

    def _cmd_joint(self, src: int, c: Command, now: int) -> None:
        if self._refused(src, c, now):
            return
        q = list(self.target)
        i = int(c.args[0])
        q[i - 1] = round(float(c.args[1]), 2)
        self._drive_joints(src, c, now, q, only=i)   # (the others are no concern of it)

    def _cmd_wheel(self, src: int, c: Command, now: int) -> None:
        if self._refused(src, c, now):
            return
        speed = c.args[0]
        seq = self._next_seq(WHEEL)
        self._can.append(dbc.encode("WHEEL_CMD", speed=int(round(speed)), distance=0, seq=seq))
        # done when the wheel reaches the speed: at most 2 x 300 mm/s at 500 mm/s^2, 1.2 s
        self.jobs.append(Job(src, c, {WHEEL: seq}, now + WHEEL_SETTLE + MARGIN, started=now))

    def _cmd_paw(self, src: int, c: Command, now: int) -> None:
        seq = self._next_seq(PAW)
        self._can.append(dbc.encode("PAW_CMD", action=int(c.args[0]), force=50, seq=seq))
        self.jobs.append(Job(src, c, {PAW: seq}, now + PAW_STROKE + MARGIN, started=now))

    def _cmd_act(self, src: int, c: Command, now: int) -> None:
        n, phase = int(c.args[0]), int(c.args[1])
        if phase != 0:
            return
        self.start_action(n, now, requester=src, command=c)

    def _cmd_stop(self, src: int, c: Command, now: int) -> None:
        for job in list(self.jobs):
            self._job_failed(job, None, now)
        for i in range(1, 5):
            if self.nodes[i].last_seen is not None:
                # held where it last reported, within its limits: a joint that overshot one
                # (a reported -10.5 deg for joint 2) is held at the limit, whose angle the
                # command can carry (mode 1 takes no angle of its own: docs/can.md)
                lo, hi = JOINT_LIMITS[i]
                self.target[i - 1] = min(max(round(self.nodes[i].value, 2), lo), hi)
            self._can.append(dbc.encode(f"JOINT{i}_CMD", angle=self.target[i - 1], speed=0,
                                        seq=self._next_seq(i), mode=1))
        self._can.append(dbc.encode("WHEEL_CMD", speed=0, distance=0,
                                    seq=self._next_seq(WHEEL)))
        # a moving joint stops where the hold finds it, not where it last reported (up to
        # 100 ms before): the commanded pose is each joint's next status once it holds
        self._rebase.update(range(1, 5))
        if self.report_done and src not in (self.id, BROADCAST):
            # carried out now (the hold and stop commands are queued): reported as such, so
            # that the sender tells it from a child that could not (fail(42), no CAN side)
            self._radio.append((src, (cmd("done"), c), int(FrameType.BROADCAST_INFO)))

    def fresh(self, n: int, now: int) -> bool:
        """Submodule ``n`` sent a status frame less than SILENCE (300 ms) ago."""
        seen = self.nodes[n].last_seen
        return seen is not None and now - seen < SILENCE

    def _cmd_status(self, src: int, c: Command, now: int) -> None:
        """Only fresh values are reported: a submodule with no status for 300 ms (or none
        ever) answers ``fail(30+n)`` in its place; with none fresh, or the child off the bus,
        the answer is a failure (Type '4'): ``fail(30)`` (no submodule answers), ``fail(41)``."""
        if self.isolated:
            self._fail(src, CODE_BLOCKED, c)
            return
        fresh = {n: self.fresh(n, now) for n in self.nodes}
        if not any(fresh.values()):
            self._fail(src, CODE_SILENT, c)
            return
        reply = [cmd("joint", i, round(self.nodes[i].value, 2)) if fresh[i] else
                 cmd("fail", CODE_SILENT + i) for i in range(1, 5)]
        reply.append(cmd("wheel", int(round(self.nodes[WHEEL].value))) if fresh[WHEEL] else
                     cmd("fail", CODE_SILENT + WHEEL))
        reply.append(cmd("paw", 1 if self.nodes[PAW].value >= 50 else 0) if fresh[PAW] else
                     cmd("fail", CODE_SILENT + PAW))
        self._radio.append((src, tuple(reply), int(FrameType.BROADCAST_INFO)))

    # -- actions (paper §V.B, Fig. 11) ------------------------------------------------------

    def start_action(self, n: int, now: int, requester: int = BROADCAST,
                     command: Command | None = None) -> bool:
        """Run preset action ``n``: announce ``act(n,0)`` to everyone, move, and announce
        ``act(n,1)`` when every joint reports done."""
        command = command or cmd("act", n, 0)
        if n not in ACTIONS:
            self._fail(requester, CODE_RANGE, command)
            return False
        self._radio.append((BROADCAST, (cmd("act", n, 0),), int(FrameType.BROADCAST_INFO)))
        if self.on_action is not None:
            self.on_action(n, "start", now)
        job = self._drive_joints(requester, command, now, list(ACTIONS[n]))
        if job is not None:
            job.notice = n
        else:  # already there
            self._action_done(n, now)
        return True

    def _action_done(self, n: int, now: int) -> None:
        self._radio.append((BROADCAST, (cmd("act", n, 1),), int(FrameType.BROADCAST_INFO)))
        if self.on_action is not None:
            self.on_action(n, "done", now)

    # -- planning --------------------------------------------------------------------------

    def _goal(self, c: Command) -> tuple[float, float, float, float]:
        """Where a move order (``movex``, ``movey``, ``movez``, ``moveto``) sends the tip:
        (x, y, z, phi), from the commanded pose (paper §V.B: relative moves are planned from
        where the arm was last sent)."""
        p = _pose(tuple(self.target))
        if c.name == "moveto":
            return float(c.args[0]), float(c.args[1]), float(c.args[2]), p.phi
        d = c.args[0]
        if c.name == "movex":
            return p.x + d, p.y + 0.0, p.z + 0.0, p.phi
        if c.name == "movey":
            return p.x + 0.0, p.y + d, p.z + 0.0, p.phi
        return p.x + 0.0, p.y + 0.0, p.z + d, p.phi

    def refusal(self, c: Command) -> tuple[int, str | None] | None:
        """(failure code, reason to log or None) if order ``c`` is refused at once, judged from
        the order and the commanded pose alone (out of reach 1, a joint outside its limits 2,
        a parameter out of range 3); None if it is carried out (or refused later, by a
        submodule) or is not such an order. A refusal reads nothing the CAN side changes and
        changes nothing but the log and the failure reply (docs/dispatcher.md)."""
        name = c.name
        if name in _MOVES:
            q, code, reason = _reach(*self._goal(c))
            return None if q is not None else (code, reason)
        if name == "joint":
            i, angle = int(c.args[0]), float(c.args[1])
            if i not in JOINT_LIMITS:
                return CODE_RANGE, None
            lo, hi = JOINT_LIMITS[i]
            return None if lo <= angle <= hi else (2, None)
        if name == "wheel":
            speed = c.args[0]
            return None if -WHEEL_MAX_SPEED <= speed <= WHEEL_MAX_SPEED else (CODE_RANGE, None)
        return None

    def refuses_all(self, dst: int, commands: tuple[Command, ...], type_: int) -> bool:
        """Would :meth:`on_message` only refuse ``commands``: a request (Types '0'-'2') to this
        robot alone whose every command :meth:`refusal` refuses? Then handling it logs and
        answers each with its failure, and nothing else changes."""
        return (type_ in REQUEST_TYPES and dst != BROADCAST and bool(commands)
                and all(self.refusal(c) is not None for c in commands))

    def _refused(self, src: int, c: Command, now: int) -> bool:
        """Refuse ``c`` if :meth:`refusal` says so."""
        refused = self.refusal(c)
        if refused is not None:
            self._refuse(src, c, now, *refused)
        return refused is not None

    def _refuse(self, src: int, c: Command, now: int, code: int, reason: str | None) -> None:
        """Answer ``c`` with failure ``code``; a move's ``reason`` goes to the log."""
        if reason is not None:
            self._note((now, f"{c.text()}: {reason}"))
        self._fail(src, code, c)

    def _move(self, src: int, c: Command, now: int) -> None:
        # the plan that refusal() judges, made once: refused here exactly when it refuses
        q, code, reason = _reach(*self._goal(c))
        if q is None:
            self._refuse(src, c, now, code, reason)
            return
        self._drive_joints(src, c, now, list(q))

    def _drive_joints(self, src: int, c: Command, now: int, q: list[float],
                      only: int | None = None) -> Job | None:
        """Coordinated motion: the joints that move arrive at about the same time.

        Planned from where the joints are (their last status, at most 100 ms old), not from
        where they were last sent, so a command that arrives mid-motion gets a sensible speed;
        no joint is given less than a quarter of its rated speed, so a stale position costs
        little time. ``only``: the one joint the order is about (``joint(n,a)``); a pose
        (a Cartesian move, an action) is about all four."""
        moves: dict[int, float] = {}
        joined: dict[int, int] = {}
        for i in (range(1, 5) if only is None else (only,)):
            a = q[i - 1]
            if abs(a - self.target[i - 1]) >= 0.005:
                moves[i] = a
                continue
            seq = self._seq[i]
            v = self.nodes[i]
            told = v.status_at is not None and now - v.status_at < SILENCE   # a fresh status
            if any(j.waiting.get(i) == seq for j in self.jobs) or (
                    told and v.state == _MOVING and v.seq == seq):
                # already sent there and still on its way (for a job, or one superseded for
                # another joint): this order waits for the same arrival (a second act(1,0)
                # used to announce act(1,1) at once, mid-motion)
                joined[i] = seq
            elif told and abs(a - v.value) >= ARRIVED_DEG:
                # sent there, but not there (its submodules restarted at rest, or a job on it
                # failed): a move, not a move to where the arm already is
                moves[i] = a
        # the arrivals this order joins are due when the jobs that sent them there said
        joined_by = max((j.deadline for j in self.jobs if set(j.waiting) & set(joined)),
                        default=now)
        if not moves:
            if not joined:
                return None
            job = Job(src, c, dict(joined), joined_by, started=now)
            self.jobs.append(job)
            return job
        dist = {i: abs(a - self._position(i)) for i, a in moves.items()}
        duration = max(max(d / RATED_SPEED[i] for i, d in dist.items()), 0.001)   # seconds
        waiting = {}
        for i, d in dist.items():
            speed = min(RATED_SPEED[i], max(RATED_SPEED[i] / 4, round(d / duration, 1)))
            seq = self._next_seq(i)
            self._can.append(dbc.encode(f"JOINT{i}_CMD", angle=round(moves[i], 2),
                                        speed=speed, seq=seq, mode=0))
            waiting[i] = seq
            self.target[i - 1] = round(moves[i], 2)
        # (a joint this order joined still arrives with its seq, though the job that sent it
        # there may have been superseded just now for another joint)
        waiting.update(joined)
        job = Job(src, c, waiting, max(now + int(duration * 2 * TICK_HZ) + 2 * MARGIN,
                                       joined_by), started=now)
        self.jobs.append(job)
        return job

    def _position(self, i: int) -> float:
        """Joint ``i``'s angle as last reported, or as last commanded before any report."""
        v = self.nodes[i]
        return v.value if v.last_seen is not None else self.target[i - 1]

    def _next_seq(self, n: int) -> int:
        """The next command sequence number for node ``n``. A new command replaces the one
        the node is running (it reports no done for that one), so an earlier job waiting for
        node ``n`` will not be carried out as ordered: it ends as superseded, with no report
        (docs/dispatcher.md), though its other submodules may still arrive. (It used to stop
        waiting for ``n`` alone and report done when the others had: ``movez(60)`` reported
        done with joint 4 sent elsewhere by a later ``joint(4,-30)``.)"""
        self._seq[n] = seq = (self._seq[n] + 1) % 256
        self._rebase.discard(n)
        for job in list(self.jobs):
            if n in job.waiting:
                self.jobs.remove(job)
                self._note((job.started, f"{job.command.text()}: superseded"))
        return seq

    def _job_done(self, job: Job, now: int) -> None:
        """Every submodule reported done: an action announces act(n,1) to everyone; any other
        order is reported ``done()`` and the order, Type '3', to its sender."""
        self.jobs.remove(job)
        if job.notice is not None:
            self._action_done(job.notice, now)
        elif self.report_done and job.requester not in (self.id, BROADCAST):
            self._radio.append((job.requester, (cmd("done"), job.command),
                                int(FrameType.BROADCAST_INFO)))

    def _job_failed(self, job: Job, code: int | None, now: int) -> None:
        if job in self.jobs:
            self.jobs.remove(job)
        if code is not None:
            self._fail(job.requester, code, job.command)

    def _fail(self, dst: int, code: int, c: Command) -> None:
        if dst == self.id:
            return
        self._radio.append((dst, (cmd("fail", code), c), int(FrameType.FAILURE)))

    def _update_deadline(self) -> None:
        if not self.jobs:                # the usual case between orders: nothing to time
            self.deadline = None
            return
        nodes = self.nodes
        best = None                      # the earliest job deadline or silence limit (tick)
        for j in self.jobs:
            t = j.deadline
            if best is None or t < best:
                best = t
            started = j.started
            for n in j.waiting:
                seen = nodes[n].last_seen
                if seen is not None:
                    t = (seen if seen > started else started) + SILENCE
                    if t < best:
                        best = t
        self.deadline = best


def _node_of(name: str) -> int:
    if name.startswith("JOINT"):
        return int(name[5])
    return WHEEL if name.startswith("WHEEL") else PAW


_STATUS, _EVENT = 0, 1


def _roles() -> dict[str, tuple[int, int, str | None]]:
    """Frame name -> (_STATUS, node, the signal NodeView.value takes or None) or (_EVENT,
    node, None), for the status and event frames of rprs.dbc (what on_can reads of a name)."""
    out: dict[str, tuple[int, int, str | None]] = {}
    for m in dbc.load().messages:
        name = m.name
        signals = {s.name for s in m.signals}
        if name.endswith("_STATUS"):
            key = next((k for k in ("angle", "speed", "opening") if k in signals), None)
            out[name] = (_STATUS, _node_of(name), key)
        elif name.startswith("EVENT"):
            out[name] = (_EVENT, int(name[5:]), None)
    return out


_ROLES = _roles()


ORDER_NAMES = frozenset(n[5:] for n in dir(Dispatcher) if n.startswith("_cmd_"))
"""The commands a child acts on as orders (``act`` only as ``act(n,0)``, the start of action
n); anything else a father could send (``done()``, ``fail(n)``, ``act(n,1)``) is news a
child reports, which it notes and never carries out."""


def is_order(c: Command) -> bool:
    """Would a child carry out ``c``, sent to it alone (:data:`ORDER_NAMES`)?"""
    return c.name in ORDER_NAMES and not (c.name == "act" and c.args[1:2] != (0,))

