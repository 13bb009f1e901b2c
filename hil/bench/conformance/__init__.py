"""The conformance kit: a PC in a ring of two with one robot under test, checking it against
docs/protocol.md clause by clause (``rprs conformance``; docs/conformance.md).

The tester is scripted, not a MAC: it plays one station (ID ``tester``) and, when a check needs
it, a forger or a third member of the ring. It invites the robot (profile ``rprs``) or starts
the static ring (profile ``paper``), then runs the checks in order on the wall clock:

===========  ================================================================================
clause        what is checked, and the figure reported
===========  ================================================================================
15, 6-13      every frame from the robot is a good frame (bytes heard, frames, failures);
              a frame of the robot's that we stepped on (it broke while our frame, begun
              after its Header, was on air) is counted apart and not held against it
34, 29, 36    it answers an invitation with BOOT ('5', Number '00') or JOIN ('6') at
              E + Ttrans, and stops announcing once acknowledged (rprs); 29 is n/a (not
              applicable, JUnit "skipped") when the answer is not a BOOT frame
23            its Header begins Ttrans after our End (median and worst gap over the turns)
26            with our frames 300 ms late, still Ttrans after our End: it resynchronises
21            a frame with nothing to say is an empty heartbeat (or, rprs, a control frame)
32            it invites the absent team robots of its gap, one poll every P = 4 of its turns,
              in turn, with the ring's mask (rprs; n/a when its gap holds none)
47, 48        our message is acknowledged in its next frame; a retransmission (same Number)
              is acknowledged again but not acted on again (its status() answered once)
              (rprs); in the paper profile nothing is acknowledged
45            its reply to our next status() takes the Number after its first reply's; ours
              are 99 and 00, so it must take the wrap for a new message (rprs)
45            with ``wrap``: about a hundred status() make it write its own Number past
              '99': each reply the next, '00' after '99' (rprs; own_counter.py)
38            a frame with a forged Source (a team robot outside the ring) is not acted on
              (rprs; n/a in the paper profile, which admits any team robot that sends)
20            with ``checksum``: our status() with a wrong crc(NNNNN) is not acted on; and
              every frame of the robot's ends with a right one
41, 15, 11    frames that break (a bad digit in the Number; Length 9999) are not acted on,
              and close our turn: the robot takes the next
44            ... after R-stagger: id x Tslot after the closure (rprs)
51            ... and its next frame tells its ring (ring(mask) or a poll's mask) (rprs)
51, 34, 49    our ring(mask) without its bit sends it back to LISTEN; invited, it answers
              JOIN (rprs)
51, 39, 40    a ring of three, the kit also playing a team robot T (rprs; n/a with a team of
              two): a ring(mask) with T's bit admits T, whose message it takes as a member's;
              a frame half a Tmax into a silent member's turn is out of turn, not acted on;
              three misses with nothing heard send it to LISTEN (cut-off); a ring(mask)
              without T, which it counted missing too, drops T
24, 44        when we fall silent it takes the turn: Tmax after its own End, plus R-stagger and
              R-pair in a ring of two (rprs), or at its End + Tmax + Ttrans (paper)
25            after our third missed turn it drops us (its masks lack us; paper: its turns
              come at its lone cadence)
===========  ================================================================================

A turn the robot misses (a bench process starved past a Tslot listens for the ring again) is
taken over as a member of the ring does, and the run goes on: the frame after it is no sample
(another is taken); three missed turns in a row stop the run (clause 25).

Times are the arrival of bytes at this PC: a Header's start is estimated as its End minus its
bytes at 9600 bit/s, so every measured gap includes the port's latency; ``tolerance`` (default
15 ms) bounds the median hand-over, and twice that 9 hand-overs in 10. The robot must run
with the real-time margins (``rprs child`` does; a flashed board on a PC bench must too,
docs/bench.md) and a team that holds both IDs. The channel must carry only the two: a frame
from any other Source stops the run (nothing is judged then).
"""
from __future__ import annotations

from .frames import _forger, _succ
from .link import (BYTE, INVITE_EVERY, MISS_LIMIT, MS, POLL_SEND, POLL_WAIT, QUIET_GAP, TMAX,
                   TSLOT, TTRANS, TWIN, SerialLink, TesterLink)
from .report import Check, ConformanceError, Heard, Report
from .tester import Tester

__all__ = ["BYTE", "INVITE_EVERY", "MISS_LIMIT", "MS", "POLL_SEND", "POLL_WAIT", "QUIET_GAP",
           "TMAX", "TSLOT", "TTRANS", "TWIN", "Check", "ConformanceError", "Heard", "Report",
           "SerialLink", "Tester", "TesterLink", "_forger", "_succ"]
