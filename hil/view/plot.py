"""The paper's Fig. 7 (rotational transfer series) drawn from a trace (docs/visualisation.md).

Three panels:

1. the timeline: one row per robot, each turn a bar from the frame's first Header bit to the
   end of its End (collided frames red and hatched), each missed turn a translucent box
   Tmax long in the missed robot's row (from the miss tick - Tmax to the miss tick), vertical
   markers for radio faults, disables and rejoins;
2. a zoom on one stretch of that window at the turn scale, so the Ttrans gaps (and a Tmax
   takeover if the window has one) are visible and dimensioned as in the paper's figure;
3. the channel utilisation (fraction of time some frame is on air) over the whole trace in
   fixed bins, with the idle ring's theoretical value and the timeline's window shaded.

The events are streamed once with bounded memory; only the drawn window is kept.

Over 500 lines on purpose: it draws one figure (the paper's Fig. 7 timeline) from one trace;
its helpers make sense only for that drawing.
"""
from __future__ import annotations

import io
import math
import os
import re
from collections import deque
from typing import Any, Iterable

from ..sim.ledger import SameHappening
from ..sim.trace import OutputFile, TraceError
from ..sim.events import (Disable, FaultEdge, FrameOnAir, Interference, Meta, Miss, Rejoin)
from .vcd import TickReorder, checked_events

__all__ = ["PlotError", "plot_trace", "FORMATS", "MAX_TURNS"]

FORMATS = ("png", "svg", "pdf")
NO_DATE = {"svg": {"Date": None}, "pdf": {"CreationDate": None}}
"""The metadata that keeps a vector format's bytes the same for the same trace (no date)."""
MAX_TURNS = 200
"""Most turns drawn in the timeline when no window is given."""
PRE_TURNS = 40
"""Turns shown before the first interesting event (miss, collision, fault, disable, rejoin)."""

_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#17becf", "#bcbd22"]


class PlotError(ValueError):
    """The plot cannot be made as asked: unsupported output format, bad window, nothing on air
    in the window, unwritable path. Unusable trace input raises :class:`hil.sim.trace.TraceError`
    (also a ``ValueError``)."""


def _colour(r: int) -> str:
    return _COLOURS[r % len(_COLOURS)]


def _nice_bin(span_ticks: int, tick_hz: int, target: int = 100) -> int:
    """A round bin width in seconds (1-2-5 steps, at least 10 ms) giving about ``target``
    bins, in ticks."""
    raw = max(span_ticks / tick_hz / target, 0.01)
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw * (1 - 1e-9))
    return max(1, round(step * tick_hz))


class _Collector:
    """One pass over the events: utilisation bins for the whole trace and the drawable items
    of one window (given, or chosen around the first interesting event)."""

    def __init__(self, meta: Meta, start: int | None, end: int | None, max_turns: int) -> None:
        self.meta = meta
        self.hz = meta.tick_hz
        self.tmax, self.ttrans = meta.tmax, meta.ttrans
        self.robots = sorted(meta.robots)
        self.q = TickReorder(2 * self.tmax + 2 * self.ttrans)
        dur = meta.duration_ticks
        self.duration = dur if isinstance(dur, int) and dur > 0 else None
        self.bin = _nice_bin(self.duration or self.hz * 10, self.hz)
        self.busy: list[int] = []
        self.run: list[int] | None = None         # current union of on-air intervals
        self.last_tick = 0
        self.given = start is not None or end is not None
        self.w_start = start if start is not None else 0
        self.w_end = end
        self.max_turns = max_turns
        # window selection state (no window given)
        self.head: list[tuple] = []
        self.head_turns = 0
        self.pre: deque[tuple] = deque()
        self.pre_turns = 0
        self.triggered: tuple | None = None
        self.picked: list[tuple] | None = None    # items of the chosen window
        self.post_turns = 0
        self.closed = False
        # dedupe / observer state
        self.dead: set[int] = set()
        self.miss_items: dict[int, list] = {}
        """Robot -> the item of its last missed turn: the observers' reports of one miss come
        a tick or a handler apart on the CPU model (hil/sim/ledger.py, ``SameHappening``)."""
        self.marks_seen = SameHappening(self.tmax // 2)
        self.totals = {"frames": 0, "collided": 0, "misses": 0, "disables": 0, "rejoins": 0,
                       "interference": 0}

    # -- intake -------------------------------------------------------------------------

    def feed(self, n: int, ev: Any) -> None:
        """Take event number ``n`` (hil/sim/events.py; kinds the figure does not draw pass)."""
        t = ev.t
        self.last_tick = t
        k = type(ev)
        q = self.q
        if k is FrameOnAir:
            s, e = ev.start, ev.end
            if s > e:
                raise TraceError(f"event {n} (frame): start {s} is after end {e}")
            self.totals["frames"] += 1
            self.totals["collided"] += ev.collided
            q.push(s, ("frame", s, e, ev.src, ev.collided, ev.aborted, ev.bytes, ev.dst), 0, n)
        elif k is Miss:
            r, by = ev.robot, ev.by
            item = self.miss_items.get(r)
            if item is None or t - item[2] > self.tmax // 2:     # (else another's report)
                # [kind, box start, box end, robot, observers, observers with a live radio]
                item = ["miss", t - self.tmax, t, r, set(), set()]
                self.miss_items[r] = item
                q.push(t - self.tmax, item, 1, n)
            item[4].add(by)
            if by not in self.dead:
                if not item[5]:
                    # counted as the run's summary counts misses: reported by a robot that
                    # could hear the air (one whose radio had failed is drawn, not counted)
                    self.totals["misses"] += 1
                item[5].add(by)
        elif k is Disable or k is Rejoin:
            r = ev.robot
            name = ev.KIND
            if self.marks_seen.first(name, r, t):     # every member reports it, not at once
                self.totals[name + "s"] += 1
                q.push(t, ("mark", t, name, r, name), 2, n)
        elif k is FaultEdge:
            hit, kind, phase = ev.robot, ev.kind, ev.phase
            if hit is not None and kind in ("fail", "recover"):
                if (kind == "fail") == (phase != "end"):
                    self.dead.add(hit)
                else:
                    self.dead.discard(hit)
            label = str(ev.spec or kind) + (" ends" if phase == "end" else "")
            q.push(t, ("mark", t, kind if phase != "end" else "fault_end", hit, label), 2, n)
        elif k is Interference:
            s, e = ev.start, ev.end
            if s > e:
                raise TraceError(f"event {n} (interference): start {s} is after end {e}")
            self.totals["interference"] += 1
            q.push(s, ("noise", s, e), 0, n)
        for tick, item in q.ready(t):
            self._take(tick, item)

    def finish(self) -> None:
        for tick, item in self.q.ready(None):
            self._take(tick, item)
        if self.run is not None:
            self._add_busy(*self.run)
            self.run = None

    # -- utilisation --------------------------------------------------------------------

    def _add_busy(self, s: int, e: int) -> None:
        b = self.bin
        while s < e:
            i = s // b
            stop = min(e, (i + 1) * b)
            if i >= len(self.busy):
                self.busy.extend([0] * (i + 1 - len(self.busy)))
            self.busy[i] += stop - s
            s = stop

    # -- window -------------------------------------------------------------------------

    def _take(self, tick: int, item: Any) -> None:
        kind = item[0]
        if kind in ("frame", "noise"):
            s, e = item[1], item[2]
            if self.run is None:
                self.run = [s, e]
            elif s <= self.run[1]:
                self.run[1] = max(self.run[1], e)
            else:
                self._add_busy(*self.run)
                self.run = [s, e]
        if self.closed:
            return
        if self.given:
            lo = item[1]
            hi = item[2] if kind in ("frame", "miss", "noise") else item[1]
            if self.w_end is not None and lo >= self.w_end:
                self.closed = True
                return
            if hi > self.w_start:
                self.picked = self.picked if self.picked is not None else []
                self.picked.append(item)
            return
        is_turn = kind == "frame"
        if self.triggered is None:
            if self.head_turns < self.max_turns:
                self.head.append(item)
                self.head_turns += is_turn
            interesting = (kind in ("miss", "mark", "noise") or (is_turn and item[4]))
            self.pre.append(item)
            self.pre_turns += is_turn
            while self.pre_turns > PRE_TURNS:
                old = self.pre.popleft()
                self.pre_turns -= old[0] == "frame"
            if interesting:
                self.triggered = item
                self.picked = list(self.pre)
                self.post_turns = self.pre_turns
                self.head = []
                self.pre.clear()
            return
        assert self.picked is not None
        if self.post_turns >= self.max_turns:
            self.closed = True
            return
        self.picked.append(item)
        self.post_turns += is_turn

    def items(self) -> list[tuple]:
        if self.picked is not None:
            return self.picked
        return self.head


# -- drawing ---------------------------------------------------------------------------------

def _unit(span_ticks: int, hz: int) -> tuple[str, float]:
    return ("ms", hz / 1000) if span_ticks < 2 * hz else ("s", hz)


def _draw_rows(ax: Any, items: list[tuple], robots: list[int], unit_div: float, x0: float,
               x1: float, labels: bool = False) -> dict[str, Any]:
    """The Fig. 7 rows: bars, missed-turn boxes, markers. Returns the legend handles."""
    from matplotlib.patches import Patch, Rectangle

    row = {r: len(robots) - 1 - i for i, r in enumerate(robots)}   # R1 on top
    h = 0.56
    bars: dict[int, list[tuple[float, float]]] = {r: [] for r in robots}
    bad: list[tuple[int, float, float, bool]] = []
    handles = {}
    for it in items:
        if it[0] != "frame":
            continue
        _, s, e, src, collided, aborted, nbytes, dst = it
        if src not in row:
            continue
        xs, w = s / unit_div, (e - s) / unit_div
        if collided or aborted:
            bad.append((src, xs, w, aborted))
        else:
            bars[src].append((xs, w))
        if labels and not (collided or aborted):
            cx = xs + w / 2
            if x0 <= cx <= x1 and w / (x1 - x0) > 0.04:
                to = "all" if dst == 7 else f"R{dst}"
                ax.text(cx, row[src], f"R{src}→{to}\n{nbytes} B", ha="center", va="center",
                        fontsize=7, color="white", clip_on=True)
    for r in robots:
        if bars[r]:
            ax.broken_barh(bars[r], (row[r] - h / 2, h), facecolors=_colour(r),
                           edgecolor="black", linewidth=0.3)
    for src, xs, w, aborted in bad:
        if aborted:     # the sender's radio died mid-frame
            ax.add_patch(Rectangle((xs, row[src] - h / 2), w, h, facecolor="white",
                                   edgecolor=_colour(src), hatch="....", linewidth=0.8))
            handles["aborted"] = Patch(facecolor="white", edgecolor="#555555", hatch="....",
                                       label="aborted frame (radio died)")
        else:
            ax.add_patch(Rectangle((xs, row[src] - h / 2), w, h, facecolor="#ffb3b3",
                                   edgecolor="#c00000", hatch="////", linewidth=0.8))
            handles["collided"] = Patch(facecolor="#ffb3b3", edgecolor="#c00000",
                                        hatch="////", label="collided frame")
    for it in items:
        if it[0] != "miss":
            continue
        _, s, e, r, observers, live = it
        if r not in row:
            continue
        if live:
            ax.add_patch(Rectangle((s / unit_div, row[r] - h / 2 - 0.08), (e - s) / unit_div,
                                   h + 0.16, facecolor=_colour(r), alpha=0.18,
                                   edgecolor=_colour(r), linestyle="--", linewidth=1.0))
            if (e - s) / unit_div > (x1 - x0) * 0.05 and x0 <= s / unit_div <= x1:
                ax.text((s + e) / 2 / unit_div, row[r], f"R{r} missed\nTmax", ha="center",
                        va="center", fontsize=7, color="#444444", clip_on=True)
            handles["miss"] = Patch(facecolor="#999999", alpha=0.3, edgecolor="#555555",
                                    linestyle="--", label="missed turn (Tmax long)")
        else:
            ax.add_patch(Rectangle((s / unit_div, row[r] - h / 2), (e - s) / unit_div, h,
                                   facecolor="none", edgecolor="#888888", linestyle=":",
                                   linewidth=1.0))
            handles["phantom"] = Patch(facecolor="none", edgecolor="#888888", linestyle=":",
                                       label="miss seen only by a failed radio")
    for it in items:
        if it[0] == "noise":
            ax.axvspan(it[1] / unit_div, it[2] / unit_div, facecolor="#dddddd",
                       edgecolor="#777777", hatch="xx", linewidth=0.5, zorder=0.6)
            handles["noise"] = Patch(facecolor="#dddddd", edgecolor="#777777", hatch="xx",
                                     label="interference (no robot)")
    style = {"fail": ("#c00000", ":", "radio fails"), "recover": ("#2a7f2a", ":", "radio back"),
             "disable": ("black", "--", "disabled"), "rejoin": ("#2a7f2a", "--", "rejoins"),
             "steal": ("#c00000", "-.", "steals the turn")}
    marks = sorted((it[1], it[2], -1 if it[3] is None else it[3], it[4])
                   for it in items if it[0] == "mark")
    grouped: list[tuple[float, str, str, str]] = []
    for t, kind, r, label in marks:
        colour, ls, text = style.get(kind, ("#7a4fa0", ":", label))
        x = t / unit_div
        if not x0 <= x <= x1:
            continue
        # one line and label per (tick, kind): disables are reported by every member
        if grouped and grouped[-1][0] == x and grouped[-1][2] == kind:
            continue
        grouped.append((x, f"R{r} {text}" if r >= 0 else text, kind, colour))
        ax.axvline(x, color=colour, linestyle=ls, linewidth=1.1, zorder=0.5)
    level = 0
    last_x = None
    span = x1 - x0
    for x, text, _kind, colour in grouped:
        level = level + 1 if last_x is not None and x - last_x < span * 0.09 else 0
        last_x = x
        ax.text(x, len(robots) - 0.5 + 0.05 + 0.32 * (level % 3), " " + text, color=colour,
                fontsize=8, ha="left", va="bottom", clip_on=False)
    ax.set_yticks([row[r] for r in robots], [f"R{r}" for r in robots])
    ax.set_ylim(-0.6, len(robots) - 0.4)
    ax.set_xlim(x0, x1)
    ax.grid(axis="x", color="#dddddd", linewidth=0.6)
    ax.set_axisbelow(True)
    return handles


def _zoom_span(items, robots, ttrans, lo=None, hi=None):
    """One cycle at the turn scale, so the Ttrans gaps show: a robot's turn up to its next
    one (the next cycle's first turn), every turn normal (every gap Ttrans, up to a quarter
    more: a handler's time on the CPU model; no collision), each frame wholly inside the
    window [``lo``, ``hi``] ticks when one is given (a frame that straddles its edge is not
    one of them). Of those, the cycles that start at
    their lowest ID (the ring's, at that time) if any does; of these, the last that ends
    before the first interesting item of the window, else the first (docs/visualisation.md,
    Fig. 7 item 2). With no whole cycle, the same choice among normal runs of |robots|
    turns, else of 2. Returns (start, end) ticks or None."""
    frames = [it for it in items if it[0] == "frame" and (lo is None or it[1] >= lo)
              and (hi is None or it[2] <= hi)]
    first = next((it[1] for it in items if it[0] in ("miss", "mark", "noise")
                  or (it[0] == "frame" and (it[4] or it[5]))), None)
    n = len(robots)

    def normal(run):
        # a hand-over's gap is Ttrans on the ideal CPU, and a handler's time more on the CPU
        # model (the command line's default: 81,115 ticks) or with a slow clock: up to a
        # quarter more (an invitation window, 10 ms, or a stagger wait is no hand-over)
        return all(not f[4] and not f[5] for f in run) and all(
            ttrans <= b[1] - a[2] <= ttrans + ttrans // 4 for a, b in zip(run, run[1:]))

    def span(run, cyc):
        ids = [f[3] for f in cyc]
        return (ids[0] == min(ids), run[0][1], run[-1][2])

    runs = []
    for i, f in enumerate(frames):           # whole cycles: R_a ... up to R_a's next turn
        j = next((j for j in range(i + 1, min(len(frames), i + n + 1))
                  if frames[j][3] == f[3]), None)
        if j is not None and normal(frames[i:j + 1]):
            runs.append(span(frames[i:j + 1], frames[i:j]))
    for k in (n, 2):
        if runs:
            break
        runs = [span(frames[i:i + k], frames[i:i + k]) for i in range(len(frames) - k + 1)
                if normal(frames[i:i + k])]
    if runs:
        runs = [r for r in runs if r[0]] or runs          # starting at the lowest ID
        before = [r for r in runs if first is not None and r[2] <= first]
        pick = before[-1] if before else runs[0]
        return pick[1], pick[2]
    if frames:
        return frames[0][1], frames[min(len(frames), n) - 1][2]
    return None


def _dimension(ax, x0, x1, y, text, colour="black"):
    ax.annotate("", xy=(x0, y), xytext=(x1, y),
                arrowprops=dict(arrowstyle="<->", color=colour, linewidth=0.9,
                                shrinkA=0, shrinkB=0))
    ax.text((x0 + x1) / 2, y + 0.12, text, ha="center", va="bottom", fontsize=8, color=colour)


_CLIP_ID = re.compile(rb'id="(p[0-9a-f]{10})"')


def _number_clip_paths(data: bytes) -> bytes:
    """Matplotlib names an SVG clip path by hashing, among other things, an object's memory
    address, so the same figure drawn twice in one process could differ there and only there.
    Renaming them clip1, clip2, ... in order of appearance makes the same trace give the same
    SVG bytes."""
    names: dict[bytes, bytes] = {}
    for m in _CLIP_ID.finditer(data):
        names.setdefault(m.group(1), b"clip%d" % (len(names) + 1))
    for old, new in names.items():
        data = data.replace(b'id="' + old + b'"', b'id="' + new + b'"')
        data = data.replace(b"url(#" + old + b")", b"url(#" + new + b")")
    return data


def plot_trace(events: Iterable[Any], out: str, start_s: float | None = None,
               end_s: float | None = None, max_turns: int = MAX_TURNS) -> dict:
    """Draw the paper's Fig. 7 from a trace's events (records or typed, meta first) into
    ``out`` (.png, .svg or .pdf).

    ``start_s``/``end_s`` bound the timeline (seconds); by default it shows at most
    ``max_turns`` turns, starting a little before the first miss, collision, fault, disable
    or rejoin (or at the first turn when the run has none). Returns a summary: ``path``,
    ``format``, ``window_s`` [start, end], ``turns`` drawn, ``zoom_s`` [first bit of the
    zoomed cycle, end of its last frame] and ``zoom_robots`` (its senders in order), the
    trace's ``frames``,
    ``collided``, ``misses`` (deduplicated), ``disables``, ``rejoins``, ``interference``,
    ``utilisation_bin_s``
    and ``utilisation`` (whole-trace mean). Raises :class:`PlotError` for an unsupported
    format, a bad window or an empty one, and :class:`hil.sim.trace.TraceError` for unusable
    events; the output file is written atomically (nothing is left on error).
    """
    ext = os.path.splitext(out)[1].lower().lstrip(".")
    if ext not in FORMATS:
        raise PlotError(f"cannot plot to {out!r}: the output must end in .png, .svg or .pdf")
    for name, v in (("start", start_s), ("end", end_s)):
        if v is not None and (not isinstance(v, (int, float)) or not v >= 0
                              or math.isinf(v)):
            raise PlotError(f"--{name} must be a number of seconds >= 0, got {v!r}")
    if start_s is not None and end_s is not None and not start_s < end_s:
        raise PlotError(f"--start {start_s} s must be before --end {end_s} s")
    if max_turns < 1:
        raise PlotError(f"max_turns must be at least 1, got {max_turns}")

    meta, rest = checked_events(events)
    hz = meta.tick_hz
    w0 = None if start_s is None else round(start_s * hz)
    w1 = None if end_s is None else round(end_s * hz)
    col = _Collector(meta, w0, w1, max_turns)
    for n, ev in rest:
        col.feed(n, ev)
    col.finish()
    items = col.items()
    frames = [it for it in items if it[0] == "frame"]
    if not col.totals["frames"]:
        raise TraceError("the trace has no frame on air: nothing to plot")
    end_tick = max(col.last_tick, col.duration or 0)
    if not frames:
        lo = (start_s or 0.0)
        hi = end_s if end_s is not None else end_tick / hz
        if lo >= end_tick / hz:
            raise PlotError(f"--start {lo:g} s is after the trace's end (it covers "
                            f"0-{end_tick / hz:g} s)")
        raise PlotError(f"no frame on air between {lo:g} s and {hi:g} s "
                        f"(the trace covers 0-{end_tick / hz:g} s)")

    # window in ticks
    if col.given:
        x0t = w0 if w0 is not None else 0
        x1t = w1 if w1 is not None else end_tick
    else:
        starts = [it[1] for it in items]
        ends = [it[2] if it[0] in ("frame", "miss", "noise") else it[1] for it in items]
        x0t, x1t = min(starts), max(ends)
        pad = max((x1t - x0t) // 50, meta.ttrans)
        x0t, x1t = max(0, x0t - pad), x1t + pad
    unit, div = _unit(x1t - x0t, hz)

    from matplotlib import rc_context
    from matplotlib.figure import Figure

    robots = col.robots
    fig = Figure(figsize=(14, 3.2 + 1.1 * len(robots)), dpi=100, layout="constrained")
    gs = fig.add_gridspec(3, 1, height_ratios=[len(robots) + 1.2, len(robots) * 0.9 + 0.6, 2.2])
    ax = fig.add_subplot(gs[0])
    ring = " ".join(f"R{r}" for r in robots)
    fig.suptitle(f"Rotational transfer series (paper Fig. 7) — ring {ring}, seed "
                 f"{meta.seed}, load {meta.load}", fontsize=13, x=0.01,
                 ha="left")
    handles = _draw_rows(ax, items, robots, div, x0t / div, x1t / div)
    ax.set_xlabel(f"time ({unit})")
    ax.set_title(f"turns {x0t / hz:.3f}–{x1t / hz:.3f} s ({len(frames)} frames); "
                 f"Tmax = {meta.tmax * 1000 / hz:g} ms, Ttrans = "
                 f"{meta.ttrans * 1000 / hz:g} ms", fontsize=10, loc="left", pad=30)
    legend = list(handles.values())
    if legend:
        fig.legend(handles=legend, loc="upper right", fontsize=8, frameon=False,
                   ncol=min(3, (len(legend) + 1) // 2), borderaxespad=0.2)

    # zoom at the turn scale
    axz = fig.add_subplot(gs[1])
    zs = _zoom_span(items, robots, meta.ttrans, *((x0t, x1t) if col.given else ()))
    zoom_robots: list[int] = []
    if zs is not None:
        z0, z1 = zs
        r0, r1 = zs
        zpad = max((z1 - z0) // 40, meta.ttrans)
        z0, z1 = z0 - zpad, z1 + zpad
        zdiv = hz / 1000
        zitems = [it for it in items if it[0] != "mark" and it[2] >= z0 and it[1] <= z1]
        zitems += [it for it in items if it[0] == "mark"]
        _draw_rows(axz, zitems, robots, zdiv, z0 / zdiv, z1 / zdiv, labels=True)
        row = {r: len(robots) - 1 - i for i, r in enumerate(robots)}
        zf = [it for it in zitems if it[0] == "frame"]
        for a, b in zip(zf, zf[1:]):
            gap = b[1] - a[2]
            if (0 < gap <= 2 * meta.ttrans and a[3] in row and b[3] in row
                    and a[2] >= r0 and b[1] <= r1):
                y = (row[a[3]] + row[b[3]]) / 2
                _dimension(axz, a[2] / zdiv, b[1] / zdiv, y,
                           f"Ttrans {gap * 1000 / hz:g} ms")
                axz.vlines([a[2] / zdiv, b[1] / zdiv], min(row[a[3]], row[b[3]]) - 0.3,
                           max(row[a[3]], row[b[3]]) + 0.3, color="#777777", linewidth=0.6)
        turn = [(it[2] - it[1]) * 1000 / hz for it in zf if r0 <= it[1] and it[2] <= r1]
        zoom_robots = [it[3] for it in zf if r0 <= it[1] and it[2] <= r1]
        axz.set_title(f"zoom on one cycle at {r0 / hz:.3f} s: each turn is one frame "
                      f"({', '.join(f'{d:.2f}' for d in turn)} ms), the next robot starts "
                      f"Ttrans after it ends", fontsize=10, loc="left")
        axz.set_xlabel("time (ms)")
        ax.axvspan(z0 / div, z1 / div, color="#bbbbbb", alpha=0.5, zorder=0)
        ax.text(z1 / div, -0.55, " zoom", fontsize=7, color="#666666", va="bottom")
    else:  # pragma: no cover - frames exist, so a zoom does too
        axz.set_visible(False)

    # utilisation over the whole trace
    axu = fig.add_subplot(gs[2])
    bw = col.bin
    nb = max(1, math.ceil(end_tick / bw))
    busy = (col.busy + [0] * nb)[:nb]
    xs = [i * bw / hz for i in range(nb + 1)]
    frac = [min(1.0, busy[i] / min(bw, max(1, end_tick - i * bw))) for i in range(nb)]
    axu.stairs(frac, xs, fill=True, color="#4c72b0", alpha=0.35)
    axu.stairs(frac, xs, color="#4c72b0", linewidth=1.0, label="measured")
    bts = meta.byte_ticks or {}
    given = [bts.get(str(r)) for r in robots]
    bt = [v for v in given if isinstance(v, int)]
    if bt and len(bt) == len(given):
        theory = sum(14 * v for v in bt) / sum(14 * v + meta.ttrans for v in bt)
        if len(set(bt)) == 1:
            label = (f"idle ring: 14×{bt[0]} / (14×{bt[0]} + {meta.ttrans}) = "
                     f"{theory:.3f}")
        else:
            label = f"idle ring (heartbeats only) = {theory:.3f}"
        axu.axhline(theory, color="#c44e52", linestyle="--", linewidth=1.2, label=label)
    axu.axvspan(x0t / hz, x1t / hz, facecolor="none", edgecolor="#d4a000", hatch="..",
                linewidth=1.0, zorder=0, label="timeline window")
    axu.set_xlim(0, end_tick / hz)
    axu.set_ylim(0, 1.05)
    axu.set_ylabel("air busy")
    axu.set_xlabel("time (s)")
    bin_s = bw / hz
    width = f"{bin_s:g} s" if bin_s >= 1 else f"{bin_s * 1000:g} ms"
    axu.set_title(f"channel utilisation, {width} bins, whole run", fontsize=10, loc="left")
    axu.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=8, ncol=3,
               frameon=False, borderaxespad=0.1)
    axu.grid(color="#dddddd", linewidth=0.6)

    buf = io.BytesIO()          # drawn whole first: a FIFO or a device gets the final bytes
    with rc_context({"svg.hashsalt": "rprs"}):   # same trace, same SVG
        fig.savefig(buf, format=ext, metadata=NO_DATE.get(ext))
    data = buf.getvalue()
    if ext == "svg":
        data = _number_clip_paths(data)
    try:
        dest = OutputFile(out, binary=True)
        try:
            dest.f.write(data)
            dest.commit()
        except BaseException:
            dest.discard()
            raise
    except OSError as exc:
        raise PlotError(f"cannot write plot {out}: {exc.strerror or exc}") from None
    total_busy = sum(col.busy)
    return {"path": out, "format": ext, "window_s": [x0t / hz, x1t / hz], "turns": len(frames),
            "zoom_s": [zs[0] / hz, zs[1] / hz] if zs is not None else None,
            "zoom_robots": zoom_robots, **col.totals, "utilisation_bin_s": bin_s,
            "utilisation": total_busy / end_tick if end_tick else 0.0}
