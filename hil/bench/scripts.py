"""Bench scripts for a person with USB radios (or the pty radio hub): ``rprs bench ...``.

``link``     listen and count what arrives: bytes, good frames, garbage, who is talking;
``cycle``    listen and time the ring: the gap between one frame's End and the next Header
             (spec: Ttrans, 5 ms), each robot's cycle, misses (gaps of about Tmax), against
             docs/protocol.md §7.2;
``latency``  join the ring as a member (the father by default) and ask a robot for its
             status: round-trip time (request submitted -> answer delivered), acknowledgement
             time, and loss; answers that refuse (``fail(42)status()``: no CAN side) are
             counted apart, with the reason.

The listener never transmits. Times are the wall-clock arrival of bytes at this PC, so they
include the serial port's latency (a few ms on USB adapters); medians and 99th percentiles
are quoted.
"""
from __future__ import annotations

import statistics
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable

from firmware_model.radio.deframer import Deframer, FrameFailed, FrameReceived, Garbage
from firmware_model.radio.frame import CONTENT_OFFSET, MAX_CONTENT
from firmware_model.timing import PC_BYTE_TICKS, TICK_HZ, TMAX_TICKS, TTRANS_TICKS

from .serial_radio import PortError, open_port


@dataclass
class HeardFrame:
    src: int
    dst: int
    num: int
    type: int
    nbytes: int
    start: int     # estimated tick of the first bit of the Header (end - bytes x byte time)
    end: int       # tick the last byte arrived
    invites: bool = False   # its Content holds poll(k,mask): an invitation window follows


MAX_FRAME_BYTES = CONTENT_OFFSET + MAX_CONTENT + 2
"""The longest frame's bytes (Header to End): the most a listener that began mid-frame hears of
it before the next Header."""


@dataclass
class Listening:
    """What a passive listener collected."""

    frames: list[HeardFrame] = field(default_factory=list)
    garbage: int = 0
    joined_mid_frame: int = 0
    """The bytes of the frame the listener began in the middle of: a first run of bytes that
    made no frame, up to one frame's worth (not counted in ``garbage``; every later run, and
    the rest of a longer one, is garbage: a channel of noise alone is garbage, not silence)."""
    failed: int = 0
    bytes: int = 0
    seconds: float = 0.0
    error: str | None = None
    """Why listening ended early (the port went away), or None; ``seconds`` is then how long
    it did listen."""
    stalls: list[tuple[int, int]] = field(default_factory=list)
    """(from, to) ticks in which the listener itself did not run (SIGSTOP, a starved machine):
    what it read then is dropped (read late, its times are unknown), and no turn across such a
    span is judged."""


SNIFFER_STALL_TICKS = 150 * TICK_HZ // 1000
"""A listener whose reads (each returns within the port's 50 ms timeout) came further apart
than this (150 ms) did not run meanwhile: a stall, not a quiet channel."""


class Sniffer:
    """Reads a serial port in a thread and deframes what arrives, with arrival ticks."""

    def __init__(self, port_spec: str, byte_ticks: int = PC_BYTE_TICKS) -> None:
        self.port = open_port(port_spec)
        self.bt = byte_ticks
        self.result = Listening()
        self._deframer = Deframer(byte_ticks=byte_ticks)
        self._mid_left = MAX_FRAME_BYTES  # bytes that may yet be a frame joined late
        self._stop = threading.Event()
        self._t0 = time.monotonic_ns()
        self._thread = threading.Thread(target=self._loop, name="sniffer", daemon=True)
        self._lock = threading.Lock()
        self.error: str | None = None
        """Why reading stopped before ``stop()`` (the port went away: a radio hub stopped, a
        USB radio unplugged), or None."""

    def tick(self) -> int:
        return (time.monotonic_ns() - self._t0) * TICK_HZ // 1_000_000_000

    def start(self) -> "Sniffer":
        """Start listening. Bytes that waited in the port before now (a pty keeps what was
        said while nobody read it) are discarded, not counted as garbage."""
        try:
            self.port.reset_input_buffer()
        except (OSError, ValueError, AttributeError):
            pass
        self._t0 = time.monotonic_ns()
        self._thread.start()
        return self

    def stop(self) -> Listening:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.port.close()
        if self.error is None:
            self.result.seconds = self.tick() / TICK_HZ
        self.result.error = self.error
        return self.result

    def snapshot(self) -> list[HeardFrame]:
        with self._lock:
            return list(self.result.frames)

    def _heard(self, heard: HeardFrame, frame) -> None:
        """A good frame (called with the lock held); subclasses may keep more of it."""
        self.result.frames.append(heard)

    def _loop(self) -> None:
        res = self.result
        last = self.tick()
        while not self._stop.is_set():
            try:
                data = self.port.read(max(1, self.port.in_waiting))
            except (OSError, ValueError, TypeError) as exc:
                if not self._stop.is_set():
                    self.result.seconds = self.tick() / TICK_HZ
                    self.error = str(exc) or type(exc).__name__
                return
            now = self.tick()
            since, last = last, now
            if now - since > SNIFFER_STALL_TICKS:
                # the read returns within its timeout: this one did not run for longer (a
                # stall); what it read describes the past at unknown times
                with self._lock:
                    res.stalls.append((since, now))
                    self._deframer.reset()
                try:
                    self.port.reset_input_buffer()    # what waits there came meanwhile too
                except (OSError, ValueError, AttributeError):
                    pass
                last = self.tick()
                continue
            if not data:
                continue
            bt = self.bt
            with self._lock:
                res.bytes += len(data)
                for ev in self._deframer.feed(data, now - (len(data) - 1) * bt, bt):
                    if isinstance(ev, FrameReceived):
                        f = ev.frame
                        n = f.nbytes
                        self._heard(HeardFrame(f.src, f.dst, f.num, f.type, n,
                                               ev.end - n * bt, ev.end,
                                               b"poll(" in f.content), f)
                    elif isinstance(ev, Garbage):
                        # we began listening mid-frame: not the ring's fault, up to one
                        # frame's worth before the first frame; the rest is garbage
                        k = min(ev.count, self._mid_left)
                        self._mid_left -= k
                        res.joined_mid_frame += k
                        res.garbage += ev.count - k
                    elif isinstance(ev, FrameFailed):
                        res.failed += 1
                    if type(ev) is not Garbage:
                        self._mid_left = 0    # a frame began: no later byte is one joined late


def listen(port: str, seconds: float, progress: Callable[[float], None] | None = None) \
        -> Listening:
    """Listen on ``port`` for ``seconds``, or until the port goes away (``error``)."""
    s = Sniffer(port).start()
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end and s.error is None:
            time.sleep(min(0.1, max(0.0, end - time.monotonic())))
            if progress is not None:
                progress(min(seconds, seconds - (end - time.monotonic())))
    finally:
        res = s.stop()
    return res


def percentile(values: list[float], p: float) -> float:
    """The ``p``-th percentile of ``values`` (nearest rank), NaN when empty."""
    v = sorted(values)
    if not v:
        return float("nan")
    k = min(len(v) - 1, max(0, round(p / 100 * (len(v) - 1))))
    return v[k]


def cycle_report(res: Listening) -> dict[str, Any]:
    """Turn timing against the spec from what a listener heard (ms). A hand-over is the gap
    after a frame that passes the turn (its End to the next Header, Ttrans by the spec); the
    gap after a frame that invites (``poll``) is an invitation window, reported apart."""
    fs = res.frames
    spec = TTRANS_TICKS * 1000 / TICK_HZ
    tmax = TMAX_TICKS * 1000 / TICK_HZ
    gaps: list[float] = []
    windows: list[float] = []
    long_gaps: list[dict[str, Any]] = []
    stalls = res.stalls
    for a, b in zip(fs, fs[1:]):
        if any(a.end <= t1 and t0 <= b.end for t0, t1 in stalls):
            continue             # the listener stalled between them: not a turn it saw
        g = (b.start - a.end) * 1000 / TICK_HZ
        (windows if a.invites else gaps).append(g)
        if g >= tmax * 0.9:
            long_gaps.append({"after": a.src, "next": b.src, "at_s": round(a.end / TICK_HZ, 3),
                              "ms": round(g, 1)})
    turns = [g for g in gaps if g < tmax / 2]
    misses = [g for g in gaps + windows if g >= tmax * 0.9]
    windows = [g for g in windows if g < tmax * 0.9]
    per: dict[int, list[int]] = {}
    for f in fs:
        per.setdefault(f.src, []).append(f.start)
    cycles = {r: statistics.median([(b - a) * 1000 / TICK_HZ for a, b in zip(v, v[1:])])
              for r, v in per.items() if len(v) > 2}
    err = [abs(g - spec) for g in turns]
    return {
        "frames": len(fs), "robots": sorted(per),
        "frames_per_robot": {r: len(v) for r, v in sorted(per.items())},
        "turn_gap_ms_median": statistics.median(turns) if turns else None,
        "turn_gap_error_ms_median": statistics.median(err) if err else None,
        "turn_gap_error_ms_p99": percentile(err, 99) if err else None,
        "spec_gap_ms": spec,
        "invitation_windows": len(windows),
        "invitation_gap_ms_median": statistics.median(windows) if windows else None,
        "misses": len(misses), "miss_gaps": long_gaps,
        "cycle_ms_median": cycles,
        "garbage_bytes": res.garbage, "joined_mid_frame_bytes": res.joined_mid_frame,
        "failed_frames": res.failed, "seconds": res.seconds, "error": res.error,
        "stalls": len(stalls),
        "stalled_s": round(sum(t1 - t0 for t0, t1 in stalls) / TICK_HZ, 3),
    }


@dataclass
class LatencyResult:
    sent: int
    replies: int
    round_trip_ms: list[float]
    ack_ms: list[float]
    failed: list[str]
    refusals: list[str] = field(default_factory=list)   # answers that were fail(code)...


def latency(runner: Any, station: Any, dst: int, count: int, timeout: float,
            progress: Callable[[int], None] | None = None) -> LatencyResult:
    """Ask ``dst`` for its status ``count`` times, one at a time, from ``station`` (a member
    on the real-time ``runner``, which the caller runs in a thread); fewer if the runner
    stops (its port went away)."""
    from firmware_model.radio.content import cmd
    from firmware_model.radio.mac import Deliver, Outcome

    from .orders import fail_reason

    replies: list[tuple[int, int]] = []
    refusals: list[str] = []
    outcomes: list[tuple[int, Any]] = []
    def observe(st: Any, a: object, now: int) -> None:
        if type(a) is Deliver and a.src == dst and a.dst == st.id:   # not its broadcasts
            replies.append((now, a.num))
            if a.commands and a.commands[0].name == "fail":
                code = int(a.commands[0].args[0])
                refusals.append("".join(c.text() for c in a.commands) +
                                f": {fail_reason(code)}")
        elif type(a) is Outcome:
            outcomes.append((now, a))
    station.add_observer(observe)

    def submit(box: list[Any], ev: threading.Event) -> None:
        # box and ev are this request's own: a request the runner's thread takes only after
        # the 5 s below have run out must not answer for the next one
        try:
            box.append((runner.sched.now, station.submit(dst, [cmd("status")], 2)))
        except ValueError as exc:
            box.append((runner.sched.now, exc))
        ev.set()
    rtt: list[float] = []
    ack: list[float] = []
    failed: list[str] = []
    sent = 0
    ended = getattr(runner, "finished", None)      # the runner stopped (its port went away)
    for i in range(count):
        if ended is not None and ended.is_set():
            break
        box: list[Any] = []
        ev = threading.Event()
        n_rep = len(replies)
        runner.sched.post(submit, box, ev)
        ev.wait(5.0)
        t_sub, msg = box[0] if box else (0, None)
        if msg is None or not hasattr(msg, "state"):    # (an error's text, or nothing)
            failed.append(str(msg))
            continue
        sent += 1
        end = time.monotonic() + timeout

        def answer(msg: Any = msg, t_sub: int = t_sub, n_rep: int = n_rep,
                   owed: bool = sent > len(rtt) + 1) -> int | None:
            """The tick of this request's reply: the first from ``dst`` since it was
            submitted; but while an earlier request went unanswered (``owed``), the first
            heard no earlier than the frame that acknowledged this one (the robot answers
            what it has taken: a reply heard before that is a late one to the earlier
            request). A reply heard before its own acknowledgement, whose first copy the
            father missed (a lost frame, a starved process), is this request's."""
            since = t_sub if not owed else next(
                (t for t, o in list(outcomes) if o.message is msg and o.delivered), t_sub)
            return next((t for t, _ in replies[n_rep:] if t >= since), None)
        while time.monotonic() < end and (answer() is None or msg.state == "sent"
                                          or msg.state == "queued") and \
                not (ended is not None and ended.is_set()):
            time.sleep(0.005)
        done = [o for t, o in outcomes if o.message is msg]
        if done and done[0].delivered:
            ack.append((next(t for t, o in outcomes if o.message is msg) - t_sub) * 1000 /
                       TICK_HZ)
        elif done:
            failed.append(done[0].reason)
        got = answer()
        if got is not None:
            rtt.append((got - t_sub) * 1000 / TICK_HZ)
        if progress is not None:
            progress(i + 1)
    station.remove_observer(observe)
    return LatencyResult(sent, len(rtt), rtt, ack, failed, refusals)


__all__ = ["Sniffer", "listen", "cycle_report", "latency", "LatencyResult", "PortError"]
