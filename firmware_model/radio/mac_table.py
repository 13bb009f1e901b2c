"""The rotational MAC as a transition table: state x event -> next state, with the rule.

``RotationalMac`` (firmware_model/radio/mac.py) is the executable form; this table is the
readable one, and the two are checked against each other:
``tests/firmware_model/radio/test_mac_table.py`` records every transition the MAC makes in a set of
simulated runs (faults, noise, failover, start-up)
and in rare paths it drives on one MAC, and requires each to be a row here, and every row to
be taken at least once. The state diagram in docs/mac.md is generated from this table
(``python -m firmware_model.radio.mac_table`` prints it; the same test checks the docs hold
it).

States: ``LISTEN`` (mode LISTEN) and the phases of a member (mode MEMBER): ``WAIT`` (for the
owner's Header until E + Tmax), ``WINDOW`` (for an invited robot's answer until E + Twin),
``QUIET`` (a frame failed before its Length: until the channel falls quiet), ``HOLD`` (our turn
starts at the deadline), ``SWITCH`` (TXEN high for Ttrans), ``SEND`` (our frame on air),
``WATCH`` (father failover: is the active PC's Header coming?).

Events: ``power on``; ``deadline`` (the state's timer expired; what it means depends on the
state, see ``RotationalMac.DEADLINE_HANDLERS``); ``frame`` (a good frame heard), ``failed
frame`` (a frame that broke after a good Header), ``garbage`` (bytes that form no frame);
``tx done`` (the last bit of our End left the radio); ``steal`` (fault injection: we wrongly
take the turn). A frame that changes nothing (an echo while deaf in SWITCH/SEND, noise) keeps
the state: such rows are listed too, so the table is complete for what the MAC does.

Sources: "paper §IV.x" for the paper's rules (E = end of the last frame heard), "designed" for
the project's own (docs/mac.md gives each one's reason).
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PAPER_PROFILE", "Transition", "TRANSITIONS", "STATES", "EVENTS", "markdown", "mermaid"]

STATES = ("LISTEN", "WAIT", "WINDOW", "QUIET", "HOLD", "SWITCH", "SEND", "WATCH")
EVENTS = ("power on", "deadline", "frame", "failed frame", "garbage", "tx done", "steal")


@dataclass(frozen=True)
class Transition:
    state: str
    event: str
    next: str
    when: str
    source: str


_T = Transition
PAPER_PROFILE = "paper profile"
"""The source of a row only the paper profile takes (docs/protocol.md §9.1; §6 and its guards
are the rprs profile's)."""
TRANSITIONS: tuple[Transition, ...] = (
    # -- start-up -------------------------------------------------------------------------
    _T("LISTEN", "power on", "LISTEN", "listen; claim after Tclaim(id) of silence", "designed"),
    _T("LISTEN", "power on", "WAIT", "paper profile: a member of the static ring of the whole "
       "team at once, waiting for the lowest ID's turn", PAPER_PROFILE),
    _T("LISTEN", "power on", "SWITCH", "paper profile: a member of the static ring at once, "
       "the lowest ID: its turn begins now", PAPER_PROFILE),
    _T("LISTEN", "frame", "LISTEN", "someone is on the air: the claim timer restarts",
       "designed"),
    _T("LISTEN", "garbage", "LISTEN", "bytes that form no frame: nothing changes (only a frame "
       "or a failed frame restarts the claim timer)", "designed"),
    _T("LISTEN", "failed frame", "LISTEN", "a frame that broke after its Header: the claim "
       "timer restarts", "designed"),
    _T("LISTEN", "frame", "SWITCH", "invited (poll names us): answer with JOIN at E + Ttrans",
       "designed"),
    _T("LISTEN", "frame", "HOLD", "a father PC hears the active PC: stands by, following the "
       "ring (its turn starts at the deadline)", "designed"),
    _T("LISTEN", "frame", "WAIT", "a father PC hears the active PC: stands by, following the "
       "ring", "designed"),
    _T("LISTEN", "frame", "WINDOW", "a father PC hears the active PC invite a robot: stands "
       "by, in that robot's window", "designed"),
    _T("LISTEN", "frame", "WATCH", "PC2 invited on a check turn: watches for PC1's Header "
       "first", "designed"),
    _T("LISTEN", "deadline", "LISTEN", "a frame is still coming in: look again 2 bytes later",
       "designed"),
    _T("LISTEN", "deadline", "WATCH", "a standby (or PC2 on a check turn) claims: watches for "
       "the other PC's Header first", "designed"),
    _T("LISTEN", "deadline", "SWITCH", "silence for Tclaim(id): claim, a ring of one",
       "designed"),
    _T("LISTEN", "deadline", "WAIT", "paper profile: silence for Tclaim(id): the static ring "
       "starts again, waiting for the lowest ID's turn", PAPER_PROFILE),
    # -- waiting for the owner ------------------------------------------------------------
    _T("WAIT", "frame", "WAIT", "a member's frame: the turn passes to its successor at E",
       "paper §IV.C"),
    _T("WAIT", "frame", "SWITCH", "the frame's sender precedes us: our turn at E + Ttrans",
       "paper §IV.C"),
    _T("WAIT", "frame", "WINDOW", "the frame invites an absent robot: its window until "
       "E + Twin", "designed"),
    _T("WAIT", "frame", "WATCH", "ID 0's turn on a PC that checks for the other PC",
       "designed"),
    _T("WAIT", "frame", "HOLD", "a frame refused as a failed one (bad checksum, outside the "
       "team, forged) in the slot before ours: id x Tslot after its End (R-stagger)",
       "designed"),
    _T("WAIT", "garbage", "WAIT", "bytes before the owner could have begun (its Ttrans)",
       "designed"),
    _T("WAIT", "garbage", "QUIET", "bytes in the owner's slot: its frame with a bad Header",
       "designed"),
    _T("WAIT", "failed frame", "QUIET", "the frame broke before its Length: wait for quiet",
       "designed"),
    _T("WAIT", "failed frame", "WAIT", "the frame broke after its Length: the turn closes at "
       "its promised end, or when its bytes stop sooner (stall gap)", "designed"),
    _T("WAIT", "failed frame", "HOLD", "... and ours is next: id x Tslot after it (R-stagger)",
       "designed"),
    _T("WAIT", "failed frame", "SWITCH", "... and we are ID 0 on a channel with idle noise "
       "(R-stagger 0, no quiet to wait for): our turn at once", "designed"),
    _T("WAIT", "deadline", "WAIT", "a Header had begun by E + Tmax: look again a byte later; "
       "or a miss, and the next owner's turn", "paper §IV.C"),
    _T("WAIT", "deadline", "SWITCH", "the owner missed: our turn at E + Tmax + Ttrans",
       "paper §IV.C"),
    _T("WAIT", "deadline", "HOLD", "the owner missed right after our own frame, nothing "
       "heard since: id x Tslot more (R-stagger)", "designed"),
    _T("WAIT", "deadline", "LISTEN", "nobody heard for a whole round", "designed"),
    _T("WAIT", "deadline", "WATCH", "the owner missed and ID 0's turn follows on a PC that "
       "checks for the other PC", "designed"),
    _T("WAIT", "frame", "LISTEN", "left out: a member's poll or ring mask lacks us (R-view); "
       "or our own ID a second time (a twin: yield, clause 38.2)", "designed"),
    _T("WAIT", "steal", "SWITCH", "fault injection: we wrongly take the turn", "fault"),
    _T("WAIT", "steal", "WATCH", "fault injection: we wrongly take ID 0's turn, on a father "
       "PC that checks for the other PC first", "fault"),
    _T("WINDOW", "steal", "SWITCH", "fault injection: we wrongly take the turn, in an "
       "invited robot's window", "fault"),
    _T("HOLD", "steal", "SWITCH", "fault injection: we take our turn before its start",
       "fault"),
    _T("LISTEN", "steal", "LISTEN", "fault injection with no turn to take: not a member",
       "fault"),
    _T("SWITCH", "steal", "SWITCH", "fault injection with no turn to take: ours has begun",
       "fault"),
    _T("SEND", "steal", "SEND", "fault injection with no turn to take: our frame is on air",
       "fault"),
    _T("QUIET", "steal", "QUIET", "fault injection ignored while a failed frame is waited out",
       "fault"),
    _T("WATCH", "steal", "WATCH", "fault injection ignored while watching for the other PC",
       "fault"),
    # -- an invitation's window -----------------------------------------------------------
    _T("WINDOW", "frame", "WAIT", "the invited robot answered: the turn passes on",
       "designed"),
    _T("WINDOW", "frame", "SWITCH", "the answer came and ours is the next turn", "designed"),
    _T("WINDOW", "frame", "HOLD", "the answer came and a lone member pauses", "designed"),
    _T("WINDOW", "frame", "WATCH", "the answer came and ID 0's turn follows on a checking PC",
       "designed"),
    _T("WINDOW", "frame", "LISTEN", "a lone member hears another robot; left out by the "
       "frame that took the window over; or a twin: yield", "designed"),
    _T("WINDOW", "frame", "WINDOW", "the poller's successor took the window over late enough "
       "and invites a robot: its window", "designed"),
    _T("WINDOW", "garbage", "WINDOW", "bytes that form no Header: keep waiting", "designed"),
    _T("WINDOW", "failed frame", "QUIET", "a frame broke before its Length: wait for quiet",
       "designed"),
    _T("WINDOW", "failed frame", "WAIT", "a frame broke after its Length: the window closes "
       "at its promised end", "designed"),
    _T("WINDOW", "failed frame", "HOLD", "... and ours is next: id x Tslot after it "
       "(R-stagger)", "designed"),
    _T("WINDOW", "failed frame", "SWITCH", "... and we are ID 0 on a channel with idle noise "
       "(R-stagger 0, no quiet to wait for): our turn at once", "designed"),
    _T("WINDOW", "deadline", "WINDOW", "a Header had begun by E + Twin: look again", "designed"),
    _T("WINDOW", "deadline", "WAIT", "no answer by E + Twin: the poller's successor's turn",
       "designed"),
    _T("WINDOW", "deadline", "SWITCH", "no answer, and ours is the next turn", "designed"),
    _T("WINDOW", "deadline", "HOLD", "no answer to a lone member: its next pause", "designed"),
    _T("WINDOW", "deadline", "WATCH", "no answer, and ID 0's turn follows on a checking PC",
       "designed"),
    # -- after a frame that broke early ---------------------------------------------------
    _T("QUIET", "garbage", "QUIET", "bytes keep coming", "designed"),
    _T("QUIET", "failed frame", "QUIET", "another frame broke before its Length: wait for quiet",
       "designed"),
    _T("QUIET", "failed frame", "WAIT", "a frame broke after its Length: the turn closes at "
       "its promised end", "designed"),
    _T("QUIET", "failed frame", "HOLD", "... and ours is next: id x Tslot after it "
       "(R-stagger)", "designed"),
    _T("QUIET", "failed frame", "SWITCH", "... and we are ID 0 on a channel with idle noise "
       "(R-stagger 0, no quiet to wait for): our turn at once", "designed"),
    _T("QUIET", "frame", "WAIT", "a good frame: resynchronise on it", "paper §IV.C"),
    _T("QUIET", "frame", "SWITCH", "a good frame, and ours is the next turn", "paper §IV.C"),
    _T("QUIET", "frame", "HOLD", "a frame refused as a failed one (bad checksum, outside the "
       "team, forged), and ours is next: id x Tslot after its End (R-stagger)", "designed"),
    _T("QUIET", "frame", "LISTEN", "left out: a member's poll or ring mask lacks us; or a "
       "twin: yield", "designed"),
    _T("QUIET", "frame", "WINDOW", "a good frame that invites a robot: its window", "designed"),
    _T("QUIET", "deadline", "QUIET", "not quiet yet: look again at the last byte + the gap",
       "designed"),
    _T("QUIET", "deadline", "WAIT", "quiet: the turn closed, the next owner's (R-stagger); or "
       "only noise until E + Tmax: a miss", "designed"),
    _T("QUIET", "deadline", "HOLD", "quiet, and ours is next: id x Tslot after the quiet "
       "(R-stagger)", "designed"),
    _T("QUIET", "deadline", "SWITCH", "only noise until E + Tmax: a miss, and ours is next",
       "paper §IV.C"),
    _T("QUIET", "deadline", "WATCH", "quiet, or a miss, and ID 0's turn follows on a PC that "
       "checks for the other PC", "designed"),
    _T("QUIET", "deadline", "LISTEN", "only noise until E + Tmax: the miss that makes a whole "
       "round unheard", "designed"),
    # -- our turn -------------------------------------------------------------------------
    _T("HOLD", "garbage", "HOLD", "bytes heard while we wait to begin", "designed"),
    _T("HOLD", "failed frame", "HOLD", "a frame abandoned while we wait to begin: no change",
       "designed"),
    _T("HOLD", "frame", "HOLD", "a frame refused as a failed one (bad checksum, outside the "
       "team, forged) while we wait to begin: no change", "designed"),
    _T("HOLD", "frame", "WAIT", "someone else sent first: resynchronise on it", "paper §IV.C"),
    _T("HOLD", "frame", "SWITCH", "a frame from the robot before us came first (a late "
       "twin's; a lone member's invitation answered after its window, clause 31): "
       "resynchronise, and ours is the next turn", "paper §IV.C"),
    _T("HOLD", "frame", "LISTEN", "heard another robot while alone; or our own ID a second "
       "time (a twin: yield, clause 38.2)", "designed"),
    _T("HOLD", "frame", "WINDOW", "a frame that invites a robot came first: its window",
       "designed"),
    _T("HOLD", "deadline", "HOLD", "a frame is coming in, or a jam not yet quiet for "
       "id x Tslot (R-stagger)", "designed"),
    _T("HOLD", "deadline", "SWITCH", "our turn: raise TXEN", "paper §IV.C"),
    _T("HOLD", "deadline", "WATCH", "ID 0's turn on a PC that checks for the other PC",
       "designed"),
    _T("SWITCH", "failed frame", "SWITCH", "deaf while switching: nothing changes",
       "paper §IV.C"),
    _T("SWITCH", "frame", "SWITCH", "deaf while switching: a frame a radio hears anyway (a "
       "bench port, an echo) changes nothing", "paper §IV.C"),
    _T("SWITCH", "garbage", "SWITCH", "deaf while switching: bytes heard change nothing",
       "paper §IV.C"),
    _T("SEND", "frame", "SEND", "our frame is on air: a frame heard meanwhile (an echo, a "
       "collision on a bench port) changes nothing", "paper §IV.C"),
    _T("SEND", "failed frame", "SEND", "our frame is on air: a failed frame heard changes "
       "nothing", "paper §IV.C"),
    _T("SEND", "garbage", "SEND", "our frame is on air: bytes heard change nothing",
       "paper §IV.C"),
    _T("SWITCH", "deadline", "SEND", "Ttrans after TXEN: the frame goes out", "paper §IV.C"),
    _T("SEND", "tx done", "WAIT", "our End is out: the successor's turn at E", "paper §IV.C"),
    _T("SEND", "tx done", "WINDOW", "we invited a robot: its window until E + Twin",
       "designed"),
    _T("SEND", "tx done", "LISTEN", "our BOOT/JOIN went out the announcement limit of times "
       "and a member never acknowledged it: to be invited again", "designed"),
    _T("SEND", "tx done", "HOLD", "a lone member pauses Twin + id x Tslot", "designed"),
    # -- father failover ------------------------------------------------------------------
    _T("WATCH", "frame", "WAIT", "the active PC's frame: follow it; PC1 on probation refuses "
       "the other PC's, which closes ID 0's slot; a checking PC stands by", "designed"),
    _T("WATCH", "frame", "WINDOW", "the active PC's frame invites a robot: its window",
       "designed"),
    _T("WATCH", "garbage", "WATCH", "bytes that form no frame: keep watching", "designed"),
    _T("WATCH", "failed frame", "QUIET", "a frame broke before its Length: wait for quiet",
       "designed"),
    _T("WATCH", "failed frame", "WAIT", "a frame broke after its Length: the turn passes at "
       "its promised end", "designed"),
    _T("WATCH", "deadline", "WAIT", "the active PC's Header is coming: stand by", "designed"),
    _T("WATCH", "deadline", "WATCH", "a frame is coming while we check after a possible "
       "deafness: read its Source first", "designed"),
    _T("WATCH", "frame", "WATCH", "a member's frame while we check: the turn after it is "
       "ours, watched again", "designed"),
    _T("WATCH", "frame", "HOLD", "the other PC's frame while we check, alone in our ring (our "
       "radio deaf, we dropped everyone): stand by; ID 0's next turn follows", "designed"),
    _T("WATCH", "deadline", "SWITCH", "no Header from the active PC: take ID 0's turn; or "
       "none in our first turn after a stall: the ring still has us, take it", "designed"),
    # -- a bench station after a stall (clause 5) -----------------------------------------
    _T("WATCH", "frame", "LISTEN", "another robot's frame in our first turn after a stall: "
       "the ring left us out meanwhile; to be invited again", "designed"),
    _T("WATCH", "deadline", "LISTEN", "a Header coming in our first turn after a stall: the "
       "ring left us out meanwhile; to be invited again", "designed"),
)


def markdown() -> str:
    """The table as Markdown (state, event, next state, when, source)."""
    rows = ["| state | event | next | when | rule |", "|---|---|---|---|---|"]
    rows += [f"| {t.state} | {t.event} | {t.next} | {t.when} | {t.source} |"
             for t in TRANSITIONS]
    return "\n".join(rows)


def mermaid() -> str:
    """A mermaid state diagram: one arrow per (state, next), labelled with its events."""
    edges: dict[tuple[str, str], list[str]] = {}
    for t in TRANSITIONS:
        if t.state == t.next:
            continue
        evs = edges.setdefault((t.state, t.next), [])
        if t.event not in evs:
            evs.append(t.event)
    lines = ["stateDiagram-v2", "    [*] --> LISTEN: power on"]
    lines += [f"    {a} --> {b}: {', '.join(evs)}" for (a, b), evs in edges.items()]
    return "\n".join(lines)


def docs_section() -> str:
    """What docs/mac.md holds between its mac-table markers."""
    return f"```mermaid\n{mermaid()}\n```\n\n{markdown()}\n"


if __name__ == "__main__":
    print(docs_section(), end="")
