"""We fall silent: the robot's takeovers (24, 44) and our drop (25).

Plain functions bound as methods of :class:`.tester.Tester` (its class body names them).
"""
from __future__ import annotations

import statistics
from typing import TYPE_CHECKING

from firmware_model.radio.frame import Frame

from .frames import _mask_of, _polls_of
from .link import BYTE, MS, TMAX, TSLOT, TTRANS, TWIN
from .report import Heard

if TYPE_CHECKING:
    from .tester import Tester


def _invites(self: Tester, f: Frame) -> bool:
    """``f`` invites a robot outside the ring of two (a ``poll(k,...)``, clause 32)."""
    return any(k not in (self.robot, self.me) for k, _ in _polls_of(f))


def _silence(self: Tester, h: Heard) -> None:
    """We stop sending: the robot's takeovers, then our drop (clauses 24, 25, 44).

    Each of our three missed turns is a takeover by the robot, timed from the End before
    it. Clause 24 is judged on the median of the offsets: a stamp that came late
    because this PC stalled (one run measured +34.5 ms, then -34 ms on the next, as the
    late stamp shortened the following gap) does not decide it. A robot on a busy PC can
    be starved past a Tslot while alone and then listen for the ring (clause 5): it
    stops sending before it has dropped us. We then bring it back into the ring (an
    invitation, or in the paper profile our frame in its static ring) and fall silent
    again, up to ``SILENCES`` times: clause 24 is judged on every takeover measured (at
    least three), clause 25 on the first silence it kept turning through."""
    t0 = self._secs()
    if self.profile == "rprs":
        rule = "max(its End + Tmax + id x Tslot, our End + Tmax + our id x Tslot + Ttrans + " \
               "4 B) + Ttrans (R-stagger, R-pair; its End + Twin after a frame of its that " \
               "invited a robot, clause 33)"
    else:
        rule = "its End + Tmax + Ttrans"
    offs: list[float] = []
    fig25: tuple[bool, str] | None = None
    cut: list[int] = []                  # frames heard before the robot stopped, each time
    for attempt in range(self.SILENCES):
        frames = self._fall_silent(h)
        our_end = self.last_end
        if self.profile == "rprs":
            def expect(prev_end: int, our_end: int = our_end) -> int:
                return max(prev_end + TMAX + self.robot * TSLOT,
                           our_end + TMAX + self.me * TSLOT + TTRANS + 4 * BYTE) + TTRANS
        else:
            def expect(prev_end: int, our_end: int = our_end) -> int:
                return prev_end + TMAX + TTRANS
        # after a frame of its that invited a robot outside the ring our turn begins at
        # its End + Twin (clause 33), and its takeover of our turn counts from there
        offs += [(b.start - expect(a.end + (TWIN if self._invites(a.frame) else 0))) / MS
                 for a, b in zip(frames, frames[1:4])]
        if len(frames) == 7 and fig25 is None:
            fig25 = self._dropped(frames[1:])
        else:
            cut.append(len(frames) - 1)
        if len(offs) >= 3 and fig25 is not None:
            break
        if attempt < self.SILENCES - 1:
            self.progress(f"robot {self.robot} stopped sending after {len(frames) - 1} "
                          f"frames while we were silent: we bring it back and fall "
                          f"silent again")
            h = self._rejoin()
    stops = (f"; it stopped sending after {', '.join(map(str, cut))} frames in "
             f"{len(cut)} of our silences" if cut else "")
    if not offs:
        self.check("24", "takes the turn when we fall silent", False, "no frame in "
                   f"{(2 * TMAX + 8 * TSLOT) / MS:.0f} ms" + stops, t0)
        return
    mid = statistics.median(offs)
    self.check("24", "takes the turn when we fall silent",
               len(offs) >= 3 and abs(mid) * MS <= self.tol,
               f"Header {mid:+.1f} ms (median of {len(offs)} takeovers: "
               f"{', '.join(f'{o:+.1f}' for o in offs)}) from {rule}" + (
                   "" if len(offs) >= 3 else "; fewer than 3 takeovers") + stops, t0)
    t0 = self._secs()
    ok, fig = fig25 if fig25 is not None else (
        False, f"it never kept turning alone for 6 frames{stops}")
    self.check("25", "drops us after our third missed turn", ok, fig, t0)


def _fall_silent(self: Tester, h: Heard) -> list[Heard]:
    """We send nothing more: the robot's frame ``h`` and up to six more, each within
    2 Tmax + 8 Tslot of the one before (fewer if it stops sending)."""
    frames = [h]
    for _ in range(6):
        nxt = self.wait_frame(frames[-1].end, 2 * TMAX + 8 * TSLOT, self.robot)
        if nxt is None:
            break
        frames.append(nxt)
    return frames


def _dropped(self: Tester, after: list[Heard]) -> tuple[bool, str]:
    """Clause 25 on the robot's frames ``after`` we fell silent: passed, and the figure."""
    if self.profile == "rprs":
        masks = [_mask_of(f.frame) for f in after]
        lacks = [i for i, m in enumerate(masks) if m is not None and not m >> self.me & 1]
        ok = bool(lacks) and lacks[0] == 2
        return ok, (f"first frame whose mask lacks us: its frame {lacks[0] + 1} after we "
                    f"fell silent (3 expected: one turn per miss, the third miss drops us)"
                    if lacks else "no frame of its ring or poll without us")
    # Its lone pause (clause 31, kept by the paper profile) is Twin + id x Tslot to
    # TXEN, the takeover's Tmax: for robot 6 in the real-time set 535 against 605 ms
    # End to Header. Each gap is taken for the nearer of the two rhythms.
    lone_gap, takeover_gap = TWIN + self.robot * TSLOT + TTRANS, TMAX + TTRANS
    gaps = [b.start - a.end for a, b in zip(after, after[1:])]
    lone = [i for i, g in enumerate(gaps) if abs(g - lone_gap) < abs(g - takeover_gap)]
    ok = bool(lone) and lone[0] == 2
    return ok, (f"gaps between its frames (ms): {', '.join(f'{g / MS:.0f}' for g in gaps)}"
                f"; lone {lone_gap / MS:.0f} (Twin + {self.robot} x Tslot + Ttrans), "
                f"takeover {takeover_gap / MS:.0f} (Tmax + Ttrans)")


def _rejoin(self: Tester) -> Heard:
    """Back into a ring with the robot after it stopped sending while we were silent
    (it listens for the ring, or was sent back to LISTEN): our invitation (rprs), or our
    frame in its static ring (paper); then a few turns, so that it counts us a member
    again before we fall silent once more."""
    if self.profile == "paper":
        h, _, _ = self._paper_join(self._secs(), since=self.now())
    else:
        h, _ = self._invite(self.now())
    return self._turns(h, 4)
