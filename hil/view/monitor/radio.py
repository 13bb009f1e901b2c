"""The monitor of a listening serial port (hil.view.monitor): what a passive sniffer hears,
the ring and missed turns inferred from it."""
from __future__ import annotations

from collections import deque

from rich.text import Text
from textual.binding import Binding

from firmware_model.timing import PC_BYTE_TICKS, TICK_HZ, TMAX_TICKS, s_to_ticks

from ...bench.scripts import HeardFrame, Sniffer

from .app import KEEP, MonitorApp, RATE_HZ, Received, TYPE_NAMES, _cut, _dst, _ids


class MonitorSniffer(Sniffer):
    """A :class:`hil.bench.scripts.Sniffer` that also keeps each frame's Content, in a buffer the
    monitor drains (so memory stays bounded however long it listens)."""

    def __init__(self, port_spec: str, byte_ticks: int = PC_BYTE_TICKS) -> None:
        super().__init__(port_spec, byte_ticks)
        self._new: list[tuple[HeardFrame, bytes]] = []

    def drain(self) -> tuple[list[tuple[HeardFrame, bytes]], int, int, int]:
        """(frames heard since the last drain, failed frames, garbage bytes, bytes) so far."""
        with self._lock:
            new, self._new = self._new, []
            r = self.result
            return new, r.failed, r.garbage, r.bytes

    def _heard(self, heard: HeardFrame, frame) -> None:
        self._new.append((heard, frame.content))


class RadioMonitorApp(MonitorApp):
    """The monitor on a serial port, listening only (see the module docstring)."""

    BINDINGS = MonitorApp.BINDINGS + [
        Binding("k", "disabled", "kill/revive: disabled (listener)"),
        Binding("r,s,n", "disabled", show=False),
    ]

    def __init__(self, port: str, window: float = 3.0, rate: float = RATE_HZ,
                 keep: int = KEEP) -> None:
        super().__init__(range(7), rate)
        self.port = port
        self.window = window
        self.sub_title = f"listening on {port}"
        self.sniffer = MonitorSniffer(port)       # PortError here: nothing started yet
        self._closed = False
        self.heard: dict[int, deque[Received]] = {r: deque(maxlen=keep) for r in self.robots}
        self.count = {r: 0 for r in self.robots}
        self.missed = {r: 0 for r in self.robots}
        self.last_heard: dict[int, int] = {}
        self.last: HeardFrame | None = None
        self.occupations = 0
        self.failed = self.garbage = self.bytes = 0
        self._ring_seen: set[int] = set()
        self.lost = False
        """Whether the port went away (the header says PORT LOST)."""

    def on_mount(self) -> None:
        self.sniffer.start()
        super().on_mount()

    def on_unmount(self) -> None:
        self.close()

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.sniffer.stop()

    def now(self) -> int:
        return self.sniffer.tick()

    def ring(self, now: int | None = None) -> tuple[int, ...]:
        """Robots heard in the last ``window`` seconds."""
        now = self.now() if now is None else now
        edge = now - s_to_ticks(self.window)
        return tuple(r for r in self.robots if r in self.last_heard and self.last_heard[r] >= edge)

    def step(self) -> None:
        frames, failed, garbage, nbytes = self.sniffer.drain()
        self.failed, self.garbage, self.bytes = failed, garbage, nbytes
        for f, content in frames:
            self.feed(f, content)
        now = self.now()
        if self.sniffer.error is not None and not self.lost:
            self.lost = True
            self.events.append(f"{now / TICK_HZ:9.3f} s  port {self.port} lost: "
                               f"{self.sniffer.error}; nothing more can be heard")
        ring = set(self.ring(now))
        for r in sorted(self._ring_seen - ring):
            self._ring_seen.discard(r)
            self.events.append(f"{now / TICK_HZ:9.3f} s  robot {r} silent for "
                               f"{self.window:g} s: out of the inferred ring")

    def feed(self, f: HeardFrame, content: bytes) -> None:
        """Account one frame heard (in arrival order)."""
        prev = self.last
        if prev is not None and f.start - prev.end >= 0.9 * TMAX_TICKS:
            ring = sorted(set(self.ring(f.start)) | {prev.src, f.src})
            if prev.src in ring and f.src in ring:
                i, j = ring.index(prev.src), ring.index(f.src)
                k = (i + 1) % len(ring)
                while k != j and ring[k] != prev.src:
                    self.missed[ring[k]] += 1
                    k = (k + 1) % len(ring)
        self.last = f
        self.last_heard[f.src] = f.end
        self.count[f.src] += 1
        heard = self.heard[f.src]
        last = heard[-1] if heard else None
        if not content and last is not None and not last.content and \
                (last.num, last.dst, last.type) == (f.num, f.dst, f.type):
            last.repeat += 1            # heartbeats in a row: one line with a count
            last.t = f.end
        else:
            heard.append(Received(f.end, f.src, f.num, f.dst, f.type,
                                  content.decode("ascii", "replace")))
        if f.src not in self._ring_seen:
            self._ring_seen.add(f.src)
            again = "again" if self.count[f.src] > 1 else "for the first time"
            self.events.append(f"{f.end / TICK_HZ:9.3f} s  robot {f.src} heard {again}")

    def header_text(self) -> Text:
        now = self.now()
        ring = self.ring(now)
        t = Text(no_wrap=True, overflow="ellipsis")
        t.append("ring ", "bold")
        t.append(f"[{_ids(ring)}]", "bold green" if ring else "bold red")
        t.append(f" (heard in the last {self.window:g} s)", "dim")
        t.append("   turn: ", "bold")
        if self.last is None:
            t.append("-", "bold cyan")
        else:
            quiet = (now - self.last.end) / TICK_HZ
            t.append(str(self.last.src), "bold cyan")
            t.append(" (last sender" + (f", quiet {quiet:.1f} s)" if quiet * TICK_HZ >
                                        TMAX_TICKS else ")"), "dim")
        t.append("\n")
        occ = sum(self.count.values()) + self.failed
        t.append("occupations ", "bold")
        t.append(f"{occ}")
        t.append(f"   failed frames {self.failed}", "red" if self.failed else "")
        t.append(f"   garbage bytes {self.garbage}   bytes {self.bytes}")
        t.append(f"   t = {now / TICK_HZ:.1f} s", "bold")
        if self.lost:
            t.append("   PORT LOST", "bold red")
        if self.paused:
            t.append("   FROZEN", "bold yellow")
        return t

    def pane_text(self, r: int, width: int, height: int) -> tuple[Text, str]:
        now = self.now()
        t = Text(no_wrap=True, overflow="ellipsis")
        if not self.count[r]:
            t.append("not heard", "dim")
            return t, "silent"
        in_ring = r in self.ring(now)
        ago = (now - self.last_heard[r]) / TICK_HZ
        t.append("in ring" if in_ring else "silent", "bold green" if in_ring else "bold red")
        t.append(f"  heard {ago:.1f} s ago\n", "dim")
        t.append(f"frames {self.count[r]}  ")
        t.append(f"missed ~{self.missed[r]}\n", "red" if self.missed[r] else "")
        t.append("heard", "bold")
        t.append("\n")
        n = max(0, height - 3)
        for m in (list(self.heard[r])[-n:] if n else []):
            body = m.content or f"({TYPE_NAMES.get(m.type, m.type)})"
            if m.repeat > 1:
                body += f" ×{m.repeat}"
            t.append(_cut(f" #{m.num:02d}→{_dst(m.dst)} {body}", width) + "\n")
        t.rstrip()
        return t, "" if in_ring else "silent"

    def default_hint(self) -> str:
        return f"passive listener on {self.port}: nothing is sent, so kill/revive/steal/noise " \
               "keys are disabled · space freezes the view · q quit"

    def action_disabled(self) -> None:
        self.flash("kill/revive/steal/noise work only on the simulator (rprs monitor without "
                   "--radio): this monitor only listens")

    def refresh_view(self) -> None:
        if self.paused:          # frozen: keep collecting, do not redraw
            if self.hint:
                self._set("#hint", Text(self.hint))
            return
        super().refresh_view()
