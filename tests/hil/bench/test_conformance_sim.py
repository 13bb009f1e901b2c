"""The conformance kit (hil/bench/conformance.py) against the project's child in simulated
time (hil/bench/conformance_sim.py): the tester a station on the simulator's air, the robot
the firmware model ``rprs child`` runs. No process, no pty, no wall clock: every hand-over is
exact to the tick, so the verdicts judge the kit's logic and the child's rules, never the
host's scheduling (the same runs on the pty hub are tests/hil/bench/test_conformance.py's timing
tier).
"""
from __future__ import annotations

import re
from xml.etree import ElementTree as ET

import pytest

import faulty_child
from hil.bench.conformance import ConformanceError, Report, Tester
from hil.bench.conformance.own_counter import NAME as OWN_WRAP
from hil.bench.conformance_sim import SimLink
from firmware_model.radio.auth import RingKey, seal
from firmware_model.radio.frame import BROADCAST, Frame
from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS
from hil.bench.conformance import MS, TTRANS


def _run(robot: int, profile: str = "rprs", team: tuple[int, ...] | None = None,
         seed: int = 1, lead_s: float = 1.0, key: RingKey | None = None,
         tolerance_ms: float = 15.0, wrap: bool = False) -> tuple[Report, str | None, SimLink]:
    """One run of the kit against robot ``robot`` (team default 0-6): its report, why it
    stopped (None if it ran to the end), and the link (the robot's events)."""
    team = tuple(range(7)) if team is None else team
    link = SimLink(robot, profile, team, seed=seed, lead_s=lead_s, key=key)
    t = Tester(link, robot, profile, team=team, key=key, tolerance_ms=tolerance_ms, wrap=wrap)
    try:
        return t.run(), None, link
    except ConformanceError as exc:
        return t.report, str(exc), link


def _verdicts(rep: Report) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for c in rep.checks:
        out.setdefault(c.clause, set()).add(c.verdict)
    return out


def _figure(rep: Report, clause: str) -> str:
    return " | ".join(c.figure for c in rep.checks if c.clause == clause)


def _table(rep: Report, stopped: str | None, link: SimLink) -> str:
    """What a failed assertion shows: the verdicts, why the run stopped, the robot's last
    MAC events."""
    return "\n".join([f"{c.clause} {c.verdict} {c.name}: {c.figure}" for c in rep.checks] +
                     rep.notes + [f"stopped: {stopped}", "robot's events:",
                                  link.event_lines()])


# ------------------------------------------------------------------- the matrix
PROTOCOL_ONLY = {"19a", "29", "32", "34", "36", "39", "40", "44", "45", "48", "51"}
"""Clauses the rprs profile adds to the paper's (the status() reply's form, the invitation,
the duty to invite, BOOT, the phantom takeover and the cut-off in a ring of three, R-stagger,
the reply's Number, the retransmission, ring views)."""


@pytest.mark.parametrize("team", ["default", "small"])
@pytest.mark.parametrize("profile", ["rprs", "paper"])
@pytest.mark.parametrize("robot", range(1, 7))
def test_the_projects_child_passes_every_clause(robot, profile, team):
    """IDs 1-6 x both profiles x the default team (0-6) and a team of two (0,ID): every
    clause passes (38 is n/a in the paper profile), no turn is missed, and the hand-overs are
    exact: in simulated time nothing is late by a host's latency, so the kit's default
    tolerance holds and the measured offsets are the child's own, zero to a byte's rounding.
    (On the pty hub, under load, the same matrix needed a 100 ms tolerance.)"""
    rep, stopped, link = _run(robot, profile, None if team == "default" else (0, robot))
    why = _table(rep, stopped, link)
    assert stopped is None and rep.passed, why
    verdicts = _verdicts(rep)
    expected = {"15", "21", "23", "24", "25", "26", "38", "41", "47"} | (
        PROTOCOL_ONLY if profile == "rprs" else set())
    assert set(verdicts) == expected, why
    assert verdicts["38"] == ({"n/a"} if profile == "paper" else {"pass"}), why
    if profile == "rprs":     # a team robot between it and us (tester 0) is its to invite
        inviting = team == "default" and robot < 6
        assert verdicts["32"] == ({"pass"} if inviting else {"n/a"}), why
        # a team of two leaves the kit no robot to play as a third member (40, 51.3)
        three = team == "default"
        assert verdicts["40"] == verdicts["39"] == ({"pass"} if three else {"n/a"}), why
        assert verdicts["51"] == ({"pass"} if three else {"pass", "n/a"}), why
        if three:
            admits, drops = [c.name for c in rep.checks if c.clause == "51"][-2:]
            assert admits.startswith("admits the robot a ring view names") and \
                drops == Tester.DROP, why
    assert all(v == {"pass"} for c, v in verdicts.items()
               if c not in ("38", "32", "39", "40", "51")), why
    assert not rep.notes, why                       # no missed turn, ours or the robot's
    offsets = [float(x) for x in re.findall(r"Header ([+-][\d.]+) ms \(median",
                                            _figure(rep, "23") + _figure(rep, "24"))]
    if profile == "rprs":
        offsets.append(float(re.search(r"Header ([+-][\d.]+) ms from E \+ Ttrans",
                                       _figure(rep, "34"))[1]))
        offsets += [float(x) for x in re.findall(r"[+-]\d+\.\d", _figure(rep, "44"))]
    assert offsets and all(abs(o) <= 0.1 for o in offsets), why


def test_the_same_seed_gives_the_same_run():
    """Deterministic: two runs with one seed give the same verdicts, figures and end tick."""
    a, _, la = _run(4, "rprs", seed=7)
    b, _, lb = _run(4, "rprs", seed=7)
    assert [(c.clause, c.verdict, c.figure) for c in a.checks] == \
        [(c.clause, c.verdict, c.figure) for c in b.checks]
    assert la.now() == lb.now() and la.events.getvalue() == lb.events.getvalue()


def test_the_testers_bytes_go_on_air_at_the_pcs_byte_time_and_come_back_with_their_ticks():
    """The tester's radio on the air: a write goes out at once (back to back after bytes of
    its own still on air), each byte 16 667 ticks; the robot answers our invitation Ttrans
    after its End, and what the tester hears comes back with the tick each byte was
    complete, the child's byte time apart."""
    link = SimLink(1, "rprs", (0, 1), lead_s=0.0)
    invite = Frame(dst=BROADCAST, src=0, num=0, type=3, content=b"poll(1,1)").encode()
    t0 = link.write(invite)
    assert t0 == link.now()
    end = t0 + len(invite) * PC_BYTE_TICKS
    link.idle(300 * MS)
    heard = link.read()
    assert heard, link.event_lines()
    boot = Frame(dst=BROADCAST, src=1, num=0, type=5, content=b"").encode()
    assert b"".join(d for d, _, _ in heard) == boot, heard             # its BOOT, all of it
    first, dt = heard[0][1], heard[0][2]
    assert dt == CHILD_BYTE_TICKS
    assert first == end + TTRANS + CHILD_BYTE_TICKS, (first - end)     # Header at E + Ttrans
    assert link.read() == []                                           # taken once
    t1 = link.write(invite)
    assert link.write(invite) == t1 + len(invite) * PC_BYTE_TICKS      # back to back


# ------------------------------------------------------------------- deliberate bugs
@pytest.mark.parametrize("fault", faulty_child.FAULTS)
def test_the_kit_names_the_cause_of_each_deliberate_bug(monkeypatch, fault):
    """The project's child with one rule broken (tests/faulty_child.py: the rotational MAC
    patched) fails exactly the clauses of that rule, with the figure that names the cause;
    every other clause passes. In simulated time the figures are exact."""
    faulty_child.patch(fault, monkeypatch.setattr)
    # (clause 32 needs robots to invite, clause 40 a robot the kit plays as a third member:
    # the default team; the others run with a team of two)
    default = fault in ("invite-every-turn", "no-cut-off", "masks-never-drop",
                        "early-takeovers")
    rep, stopped, link = _run(1, "rprs", None if default else (0, 1),
                              wrap=fault == "own-numbers-skip-00")
    why = _table(rep, stopped, link)
    failed = {c.clause for c in rep.checks if c.verdict == "FAIL"}
    expected = {"late-turn": {"23", "26", "24"}, "long-length": {"15"}, "no-ack": {"47", "48"},
                "boot-01": {"29"}, "no-stagger": {"44", "24"}, "late-answer": {"34"},
                "invite-every-turn": {"32"}, "deaf-to-masks": {"51"},
                "no-cut-off": {"40"}, "masks-never-drop": {"51"},
                "early-takeovers": {"39"}, "numbers-do-not-wrap": {"45"},
                "own-numbers-skip-00": {"45"}, "status-reply-type-2": {"19a"}}[fault]
    assert failed == expected, why
    if fault == "long-length":         # no good frame: the run stops at the invitation
        assert stopped is not None and "answered 5 invitations in a row with failed " \
            "frames" in stopped and "a Length longer than the Content" in stopped, why
        assert "a Length longer than the Content" in _figure(rep, "15"), why
        return
    assert stopped is None, why
    if fault == "late-turn":           # 20 ms late: every hand-over and takeover
        assert "Header +20.0 ms (median)" in _figure(rep, "23"), why
        assert "Header +20.0 ms (median of 3)" in _figure(rep, "26"), why
        assert "takeovers: +20.0, +20.0, +20.0" in _figure(rep, "24"), why
    elif fault == "no-ack":
        assert _figure(rep, "47") == "no ack", why
        assert _figure(rep, "48").startswith("re-acknowledged: no"), why
    elif fault == "boot-01":
        assert _figure(rep, "29") == "Type '5', Number '01'", why
    elif fault == "no-stagger":        # id x Tslot = 80 ms early after each uncertain closure
        assert _figure(rep, "44").startswith("its Header -80.0, -80.0 ms"), why
        assert "takeovers: -80.0, -80.0, -80.0" in _figure(rep, "24"), why
    elif fault == "late-answer":
        assert _figure(rep, "34").startswith("Type '5', Header +40.0 ms"), why
    elif fault == "deaf-to-masks":     # it kept its turn after our ring(1)
        told, left_out, three, drop = [c for c in rep.checks if c.clause == "51"]
        assert told.verdict == "pass" and left_out.verdict == "FAIL", why
        assert three.verdict == drop.verdict == "n/a", why       # a team of two
        assert left_out.figure.startswith("it kept its turn: its frame 5 ms after our "
                                          "ring(1)"), why
    elif fault == "no-cut-off":        # still a member after 3 misses with nothing heard
        assert "then its next frame" in _figure(rep, "40") and \
            "(still a member)" in _figure(rep, "40"), why
    elif fault == "numbers-do-not-wrap":   # our 00 after 99 taken for a duplicate
        assert _figure(rep, "45").startswith("its replies' Numbers: 01, to our 99 and 00; "
                                             "no new reply"), why
    elif fault == "own-numbers-skip-00":   # read right, written wrong: only the long step
        assert [c.name for c in rep.checks if c.verdict == "FAIL"] == [OWN_WRAP], why
        assert _figure(rep, "45").endswith("after '99' its next message was '01', not '00' "
                                           "('99' wraps to '00')"), why
    elif fault == "early-takeovers":   # it acknowledged the phantom's message
        assert _figure(rep, "39").endswith("frames acting on it: 1"), why
    elif fault == "masks-never-drop":  # only the drop of the ring of three fails
        assert [c.name for c in rep.checks if c.verdict == "FAIL"] == [Tester.DROP], why
        assert "told ring 7 (the ring of two: 3; of three: 7)" in _figure(rep, "51"), why
    elif fault == "status-reply-type-2":   # counted by its commands alone, it passed
        assert _figure(rep, "19a").startswith("its reply: Type '2' ") and \
            _figure(rep, "19a").endswith("; want Type '4' fail(code)status()"), why
    elif fault == "invite-every-turn":
        assert "invitations 1, 1, 1" in _figure(rep, "32") and \
            "turns apart, not every 4" in _figure(rep, "32"), why


def test_a_robot_that_stops_after_a_refused_frame_fails_clause_53_by_name(monkeypatch):
    """An authenticated robot that refuses our forged frame but never takes the turn it
    closed: the run stops there. The kit used to stop with no row for clause 53, a message
    blaming clause 41, and JUnit XML with no failure (a CI would have passed the robot). Now
    clause 53 is a FAIL row, the stop names it, and the XML carries the stop as an error."""
    faulty_child.patch("silent-after-refused", monkeypatch.setattr)
    rep, stopped, link = _run(1, "rprs", (0, 1), key=RingKey(bytes(range(16))))
    why = _table(rep, stopped, link)
    assert stopped is not None and "(clause 53:" in stopped and "clause 41" not in stopped, why
    c53 = [c for c in rep.checks if c.clause == "53"]
    assert [c.verdict for c in c53] == ["FAIL"], why
    assert c53[0].figure.startswith("it missed its turn after it 3 times in a row"), why
    assert not rep.passed and rep.stopped == stopped
    suite = ET.fromstring(rep.junit())
    assert suite.get("errors") == "1" and suite.get("failures") != "0", why
    err = [c.find("error") for c in suite.iter("testcase") if c.find("error") is not None]
    assert len(err) == 1 and err[0].get("message") == f"stopped: {stopped}"


def test_frames_with_a_wrong_tag_earn_the_robot_no_verdict_but_clause_52s(monkeypatch):
    """An authenticated robot that checks our tags right but signs its own frames with
    another key: every member refuses every frame of its (clause 53). The kit used to judge
    their Content anyway: "answers an invitation" (34), its BOOT's Number (29), acks (36, 47,
    48) passed on frames nobody may act on. Now such a frame counts for its timing only:
    clause 52 fails by name, and nothing it carries passes a clause."""
    import firmware_model.radio.auth as auth_mod
    key, other = RingKey(bytes(range(16))), RingKey(bytes(16))
    seal = auth_mod.seal
    monkeypatch.setattr(auth_mod, "seal", lambda k, *a: seal(other, *a))
    rep, stopped, link = _run(1, "rprs", (0, 1), key=key)
    why = _table(rep, stopped, link)
    verdicts = _verdicts(rep)
    assert verdicts.get("52") == {"FAIL"} and "no valid tag" in _figure(rep, "52"), why
    for clause in ("34", "29", "36", "47", "48"):
        assert "pass" not in verdicts.get(clause, set()), (clause, why)


@pytest.mark.parametrize("robot, team, key", [
    (1, None, None), (6, (0, 6), None), (3, None, RingKey(bytes(range(16))))],
    ids=["1-default", "6-small", "3-auth"])
def test_the_projects_child_runs_its_own_number_past_99_with_wrap(robot, team, key):
    """``--wrap``: about a hundred status() orders make the child write its own counter
    past '99' (clause 45); every reply is the next Number, '00' after '99', and every other
    clause still passes. The paper profile has nothing that makes a robot send: n/a."""
    rep, stopped, link = _run(robot, "rprs", team, key=key, wrap=True)
    why = _table(rep, stopped, link)
    assert stopped is None and rep.passed, why
    own = [c for c in rep.checks if c.name == OWN_WRAP]
    assert [c.verdict for c in own] == ["pass"], why
    first, last = re.search(r"'(\d\d)' to '(\d\d)', each the next; '99' then '00'",
                            own[0].figure).groups()
    assert last in ("00", "01") and int(first) < 10, why
    rep, stopped, link = _run(robot, "paper", team, wrap=True)
    assert [c.verdict for c in rep.checks if c.name == OWN_WRAP] == ["n/a"], \
        _table(rep, stopped, link)


@pytest.mark.parametrize("profile", ["rprs", "paper"])
@pytest.mark.parametrize("team, tester", [(None, 1), (None, 6), ((0, 1), 1)],
                         ids=["default-1", "default-6", "small-1"])
def test_the_father_passes_every_clause_it_can_be_judged_on(profile, team, tester):
    """Robot 0 is what ``rprs father`` runs (a PC's byte time, no submodule). It keeps every
    rule of the ring a child keeps; it acknowledges our status() but answers none (clause
    19a), so 48 judges the acknowledgement only and both 45s are n/a, and in the ring of three
    T's message is acknowledged with no reply. With tester 6 its gap holds 1-5, which it
    invites (clause 32)."""
    team = tuple(range(7)) if team is None else team
    link = SimLink(0, profile, team, tester=tester, seed=1)
    t = Tester(link, 0, profile, tester=tester, team=team, wrap=True)
    try:
        rep, stopped = t.run(), None
    except ConformanceError as exc:
        rep, stopped = t.report, str(exc)
    why = _table(rep, stopped, link)
    assert stopped is None and rep.passed and not rep.notes, why
    verdicts = _verdicts(rep)
    assert verdicts["45"] == {"n/a"}, why
    assert all("answers no order (clause 19a)" in c.figure for c in rep.checks
               if c.clause == "45"), why
    if profile == "rprs":
        assert verdicts["47"] == verdicts["48"] == {"pass"}, why
        assert "only the acknowledgement is seen" in _figure(rep, "48"), why
        assert verdicts["32"] == ({"pass"} if tester == 6 else {"n/a"}), why
        assert ("(the father answers none)" in _figure(rep, "51")) == (len(team) > 2), why


def test_a_robot_deaf_to_masks_does_not_admit_the_third_member_a_mask_names(monkeypatch):
    """Clause 51.3 in the ring of three the kit plays (default team): a robot that reads no
    ``ring(mask)`` never admits T, so T's message is an outsider's to it (clause 38.3) and is
    not acknowledged; the kit names that, besides the mask without its bit it ignored."""
    faulty_child.patch("deaf-to-masks", monkeypatch.setattr)
    rep, stopped, link = _run(1, "rprs")
    why = _table(rep, stopped, link)
    told, left_out, three, drop = [c for c in rep.checks if c.clause == "51"]
    assert (told.verdict, left_out.verdict, three.verdict) == ("pass", "FAIL", "FAIL"), why
    assert three.figure.startswith("T's status() never acknowledged; replies to T: 0"), why


# ------------------------------------------------------------------- the seam
def test_both_links_have_the_seams_methods_with_its_signatures():
    """``SerialLink`` and ``SimLink`` are ``TesterLink``s: every method the Protocol declares,
    with the same parameters and return annotation (hil is outside mypy's packages, so this
    test holds them to it)."""
    import inspect

    from hil.bench.conformance import SerialLink, TesterLink
    names = [n for n, v in vars(TesterLink).items() if inspect.isfunction(v) and
             not n.startswith("_")]
    assert sorted(names) == ["close", "idle", "now", "read", "write"]
    for cls in (SerialLink, SimLink):
        for n in names:
            want, got = inspect.signature(getattr(TesterLink, n)), \
                inspect.signature(getattr(cls, n))
            assert list(got.parameters) == list(want.parameters), (cls, n)
            assert got.return_annotation == want.return_annotation, (cls, n)


# ------------------------------------------------------------------- the kit started late
def test_the_tester_hears_nothing_from_before_it_started():
    """As a port opened when the kit starts: the robot's frames before then (it claimed the
    channel and ran alone for seconds) are not heard; they once reached the kit as its
    first frames, and its first frame answered one of them seconds late."""
    link = SimLink(1, "paper", tuple(range(7)), lead_s=5.0)
    assert '"ev":"tx"' in link.events.getvalue()               # it did send before
    assert link.read() == []


@pytest.mark.parametrize("lead_s", [3.0, 11.0])
@pytest.mark.parametrize("robot", range(1, 7))
def test_a_paper_robot_that_ran_alone_before_the_kit_started_passes(robot, lead_s):
    """The paper profile with the default team: the robot alone in its static ring of seven
    counts misses of the absent robots from its power-on, and drops them all after three
    rounds (about 11 s). The kit once counted their misses from its own start: started 3 s
    after the robot, robot 3 failed clause 23 (a takeover timed as a hand-over, +600 ms) and
    robot 1 missed turns; started 11 s after, the robot took our turn over where our frame
    began, dropped us, and the run stopped for every ID. The kit now listens until the
    robot runs alone (its lone pause, shorter than Tmax) and joins it then."""
    rep, stopped, link = _run(robot, "paper", lead_s=lead_s)
    why = _table(rep, stopped, link)
    assert stopped is None and rep.passed, why
    assert not rep.notes, why
    assert all(v <= {"pass", "n/a"} for v in _verdicts(rep).values()), why


def test_the_serial_link_stamps_and_sleeps_as_the_kit_always_did(monkeypatch):
    """``SerialLink`` is the kit's port and wall clock as before the seam: bytes read are
    stamped the last one now and each before it a byte time earlier, a write is stamped when
    it is made, ``idle`` sleeps the ticks on the wall clock, ``close`` closes the port."""
    import hil.bench.conformance.link as kit
    from firmware_model.timing import TICK_HZ

    class Port:
        def __init__(self) -> None:
            self.rx, self.tx, self.closed = b"", [], False

        @property
        def in_waiting(self) -> int:
            return len(self.rx)

        def read(self, n: int) -> bytes:
            out, self.rx = self.rx[:n], self.rx[n:]
            return out

        def write(self, data: bytes) -> None:
            self.tx.append(data)

        def close(self) -> None:
            self.closed = True

    port, clock, slept = Port(), [5_000_000_000], []
    monkeypatch.setattr(kit, "open_port", lambda name: port)
    monkeypatch.setattr(kit.time, "monotonic_ns", lambda: clock[0])
    monkeypatch.setattr(kit.time, "sleep", slept.append)
    link = kit.SerialLink("/dev/ttyX")
    clock[0] += 2_000_000                                       # 2 ms on
    assert link.now() == 2 * MS
    port.rx = b"abc"
    assert link.read() == [(b"abc", 2 * MS - 2 * kit.BYTE, kit.BYTE)]
    assert link.read() == []
    assert link.write(b"xyz") == 2 * MS and port.tx == [b"xyz"]
    link.idle(kit.POLL_WAIT)
    link.idle(kit.POLL_SEND)
    assert slept == [kit.POLL_WAIT / TICK_HZ, kit.POLL_SEND / TICK_HZ] == [0.0003, 0.0002]
    link.close()
    assert port.closed


# ------------------------------------------------------------------- the authenticated profile
KEY = RingKey(bytes.fromhex("000102030405060708090a0b0c0d0e0f"))
"""tests/firmware_model/radio/test_auth.py's ring key."""


def _talked_over(link: SimLink, robot: int) -> list[str]:
    """Every transmission of the tester's that overlapped one of the robot's on the air."""
    ours = [(a, b) for r, a, b, _ in link.transmissions if r != robot]
    theirs = [(a, b) for r, a, b, _ in link.transmissions if r == robot]
    return [f"ours {s / MS:.1f}-{e / MS:.1f} ms, its {a / MS:.1f}-{b / MS:.1f} ms"
            for s, e in ours for a, b in theirs if a < e and s < b]


@pytest.mark.parametrize("robot, tolerance_ms, lead_s", [
    (1, 100, 0.5),    # test_auth.py's run: clause 15 failed, its claim cut
    (3, 100, 0.65),   # five invitations in a row onto its lone member's frames
    (5, 15, 1.0),     # the default tolerance: its claim cut
])
def test_the_kit_never_sends_over_an_authenticated_childs_frame(robot, tolerance_ms, lead_s):
    """``rprs conformance --auth-key`` against ``rprs child --auth-key`` (team 0,ID) in
    simulated time: every clause passes, 52 and both 53s included, and no frame of the
    tester's is on air with one of the robot's. Signed, the robot's claim (a BOOT, clause 28)
    lasts 38.5 ms and its lone member's frames 48: the kit sent its first invitation as its
    listening ended, onto a claim begun before, and the next ones when an invitation's window
    ran out, onto its lone member's next frame. The frame it cut broke, for the kit, only at
    the robot's next Header, R-stagger after our End (105 ms for robot 1), beyond the 100 ms
    tolerance: clause 15 failed against the robot, as on the pty hub ("3 failed, first
    failed at byte 16 (content): 0x0f", a Header where Content was due)."""
    rep, stopped, link = _run(robot, "rprs", (0, robot), lead_s=lead_s, key=KEY,
                              tolerance_ms=tolerance_ms)
    why = _table(rep, stopped, link)
    assert stopped is None and rep.passed, why
    assert [c.clause for c in rep.checks].count("53") == 2 and "52" in _verdicts(rep), why
    verdicts = _verdicts(rep)
    # team 0,ID: nobody to invite, nobody for the kit to play as a third member
    assert (verdicts["32"], verdicts["39"], verdicts["40"], verdicts["51"]) == (
        {"n/a"}, {"n/a"}, {"n/a"}, {"pass", "n/a"}), why
    assert all(v == {"pass"} for c, v in verdicts.items()
               if c not in ("32", "39", "40", "51")), why
    assert "collision" not in _figure(rep, "15"), why
    assert _talked_over(link, robot) == [], why


@pytest.mark.parametrize("robot", range(1, 7))
def test_an_authenticated_child_passes_every_clause_with_either_team(robot):
    """The authenticated profile for every ID, the default team and a team of two: every
    clause passes (52, and 53 twice besides the rprs profile's), with no missed turn, and
    the tester never sends while the robot does. (Robot 5 with the team 0,5 had its claim
    cut by the kit's first invitation.)"""
    for team in (None, (0, robot)):
        rep, stopped, link = _run(robot, "rprs", team, key=KEY)
        why = _table(rep, stopped, link)
        assert stopped is None and rep.passed and not rep.notes, why
        verdicts = _verdicts(rep)
        assert {"52", "53"} <= set(verdicts), why
        assert verdicts["32"] == ({"pass"} if team is None and robot < 6 else {"n/a"}), why
        # the ring of three the kit plays (40, 51.3) needs a third team robot
        assert verdicts["40"] == verdicts["39"] == ({"pass"} if team is None else {"n/a"}), why
        assert verdicts["51"] == ({"pass"} if team is None else {"pass", "n/a"}), why
        assert all(v == {"pass"} for c, v in verdicts.items()
                   if c not in ("32", "39", "40", "51")), why
        assert _talked_over(link, robot) == [], why
        # clause 21: the profile has no heartbeat, its idle frame is a control frame (the kit
        # said "heartbeat", reading the frame with its auth taken off)
        kinds = next(c.figure for c in rep.checks if c.clause == "21")
        assert kinds == "frame kinds: control", why


class _Air:
    """A link whose bytes the test hands in: what the kit reads, stamped as given."""

    def __init__(self) -> None:
        self.t, self.rx, self.tx = 0, [], []

    def now(self) -> int:
        return self.t

    def read(self) -> list[tuple[bytes, int, int]]:
        out, self.rx = self.rx, []
        return out

    def write(self, data: bytes) -> int:
        self.tx.append(data)
        return self.t

    def idle(self, ticks: int) -> None:
        self.t += ticks

    def close(self) -> None:
        pass


@pytest.mark.parametrize("read_before_we_send", [True, False])
def test_a_frame_our_transmission_cut_is_ours_when_the_next_header_comes_late(
        read_before_we_send):
    """A signed frame of robot 1's, 15 bytes in when our frame goes out: we hear no more of
    it (deaf while on air), and its next Header comes R-stagger after our End, 105 ms, beyond
    a 100 ms tolerance. The cut frame is a collision of ours, not a failed frame of the
    robot's, whether its bytes reached us before our write or (a port's latency) after it.
    It once failed clause 15 as "first failed at byte 16 (content): 0x0f", judged at that
    next Header."""
    air = _Air()
    t = Tester(air, 1, "rprs", team=(0, 1), tolerance_ms=100, key=KEY)
    bt = CHILD_BYTE_TICKS
    robots = seal(KEY, BROADCAST, 1, 0, 5, b"", 1).encode()
    air.t = 1000 * MS
    heard = (robots[:15], air.t - MS - 14 * bt, bt)      # its 16th byte not yet complete
    if read_before_we_send:
        air.rx.append(heard)
        t._poll_rx()
    end = t._write(t.frame(b"poll(1,1)").encode())
    if not read_before_we_send:          # its bytes, on air before ours, read after our write
        air.rx.append((heard[0], air.t + 2 * MS, bt))
        t._poll_rx()
    nxt = seal(KEY, BROADCAST, 1, 0, 5, b"", 2).encode()
    air.rx.append((nxt, end + 105 * MS, bt))
    t._poll_rx()
    assert (t.bad, t.collided) == (0, 1), t.first_failure
    assert [h.frame.src for h in t.heard] == [1]              # its next frame, whole


class _BlockingPort:
    """A serial port as pyserial's with a read timeout (hil/bench/serial_radio.py: 50 ms) on
    a fake clock: a read with nothing heard waits until a byte comes or the timeout runs out.
    ``frames``: (tick its first byte is complete, bytes) the robot sends; ``answer(t)``
    gives what to schedule after each write ending at tick ``t``."""

    TIMEOUT = 50 * MS

    def __init__(self, clock: list[int], frames, answer) -> None:
        self.clock, self.answer, self.writes = clock, answer, []
        self.bytes = [(t + i * PC_BYTE_TICKS, b) for t, f in frames for i, b in enumerate(f)]

    def _tick(self) -> int:
        return self.clock[0] * 16 // 1000                     # ns -> ticks (16 MHz)

    @property
    def in_waiting(self) -> int:
        return sum(1 for t, _ in self.bytes if t <= self._tick())

    def read(self, n: int) -> bytes:
        if not self.in_waiting:                               # blocks: a byte, or the timeout
            nxt = min((t for t, _ in self.bytes), default=None)
            until = self._tick() + self.TIMEOUT
            self.clock[0] = (until if nxt is None else min(nxt, until)) * 1000 // 16
        ready = [x for x in self.bytes if x[0] <= self._tick()][:n]
        self.bytes = self.bytes[len(ready):]
        return bytes(b for _, b in ready)

    def write(self, data: bytes) -> None:
        self.writes.append((self._tick(), data))
        end = self._tick() + len(data) * PC_BYTE_TICKS
        self.bytes += [(t + i * PC_BYTE_TICKS, b) for t, f in self.answer(end)
                       for i, b in enumerate(f)]

    def close(self) -> None:
        pass


def test_on_a_serial_port_the_invitation_after_a_lone_members_frame_comes_in_its_pause(
        monkeypatch):
    """Robot 1 runs alone (a frame every Twin + 1 x Tslot: TXEN 130 ms after its End) and
    does not hear our first invitation. Its next frame comes in that invitation's window;
    we invite Ttrans after it, and on a serial port whose read waits up to 50 ms for a byte
    the invitation still begins within one such wait of that instant, in the robot's pause.
    With a look at the port before the invitation and another as it was written, it began
    about 150 ms after the robot's End, onto its next frame, every time: on the pty hub the
    robot never answered, and the run stopped after 400 invitations."""
    import hil.bench.conformance.link as kit
    from hil.bench.conformance import TWIN, TSLOT

    clock = [0]
    monkeypatch.setattr(kit.time, "monotonic_ns", lambda: clock[0])
    monkeypatch.setattr(kit.time, "sleep", lambda s: clock.__setitem__(
        0, clock[0] + int(s * 1e9)))
    lone = seal(KEY, BROADCAST, 1, 3, 3, b"poll(0,2)", 7).encode()
    boot = seal(KEY, BROADCAST, 1, 0, 5, b"", 8).encode()
    writes = []

    def answer(end: int):
        writes.append(end)
        if len(writes) == 1:               # not heard: its next lone frame, in the window
            return [(end + 60 * MS, lone)]
        return [(end + TTRANS + PC_BYTE_TICKS, boot)]    # heard: its BOOT, at E + Ttrans
    port = _BlockingPort(clock, [], answer)
    monkeypatch.setattr(kit, "open_port", lambda name: port)
    t = Tester("/dev/ttyX", 1, "rprs", team=(0, 1), tolerance_ms=100, key=KEY)
    h, end = t._invite(-1)
    assert h.frame.type == 5 and len(port.writes) == 2, port.writes
    lone_end = writes[0] + 60 * MS + (len(lone) - 1) * PC_BYTE_TICKS
    began = port.writes[1][0] - lone_end
    assert began <= TTRANS + _BlockingPort.TIMEOUT + MS, began / MS
    assert began < TWIN + TSLOT, began / MS           # before its next TXEN


# ------------------------------------------------------------------- the checksum extension
@pytest.mark.parametrize("robot", [1, 6])
def test_a_child_with_the_checksum_passes_every_clause_and_refuses_a_wrong_checksum(robot):
    """``rprs conformance --checksum`` against ``rprs child --checksum`` (clause 20): every
    frame of the robot's ends with a right ``crc(NNNNN)``, our status() with its checksum
    wrong in one digit is not acted on and closes our turn (clause 43: R-stagger after our
    End), and every other clause passes with the kit's frames checksummed."""
    team = (0, robot)
    link = SimLink(robot, "rprs", team, checksum=True)
    t = Tester(link, robot, "rprs", team=team, checksum=True)
    rep = t.run()
    why = _table(rep, None, link)
    assert rep.passed and not rep.notes, why
    twenty = [c for c in rep.checks if c.clause == "20"]
    assert [c.verdict for c in twenty] == ["pass", "pass"], why
    assert "frames acting on it: 0" in twenty[0].figure, why
    # a good frame without a right crc closes the turn at its own End, uncertain (clause
    # 43): R-stagger from there, id x Tslot + Ttrans
    assert f"its next frame {robot * 80 + 5} ms after" in twenty[0].figure, why
    assert twenty[1].figure.endswith("all right"), why


def test_a_robot_without_the_checksum_fails_clause_20_by_name():
    """Checked with ``--checksum``, a robot that runs without it: its frames carry no
    ``crc(NNNNN)``, and it obeys our status() whose checksum is wrong: both verdicts of
    clause 20 fail, saying so (it ignores our ``crc`` commands, clause 20: the rest passes)."""
    link = SimLink(1, "rprs", (0, 1))
    t = Tester(link, 1, "rprs", team=(0, 1), checksum=True)
    try:
        rep = t.run()
    except ConformanceError:
        rep = t.report
    why = _table(rep, None, link)
    assert {c.clause for c in rep.checks if c.verdict == "FAIL"} == {"20"}, why
    refusal, frames = [c for c in rep.checks if c.clause == "20"]
    assert "frames acting on it: 1" in refusal.figure, why        # it obeyed it
    assert re.match(r"(\d+) frames, \1 not: Number 00: no crc\(NNNNN\)", frames.figure), why


def test_the_kit_sends_its_new_message_again_when_the_robot_lost_its_frame():
    """A busy host loses a frame now and then. The kit's new message of clause 45 (our
    Number '00' after '99') went out once, so a frame the robot did not take left it without
    a reply and failed a robot that did nothing wrong (seen once on the pty hub). Here the
    first frame carrying it breaks on the air (its Type digit): the kit sends the message
    again, with its Number, until the robot acknowledges it, and every clause passes."""
    link = SimLink(1, "rprs", (0, 1))
    real, copies = link.write, []

    def write(data: bytes) -> int:
        if b"status()" in data and data[5:7] == b"00":
            if not copies:
                data = data[:7] + b"x" + data[8:]      # a bad Type digit: not acted on
            copies.append(data)
        return real(data)
    link.write = write                                   # type: ignore[method-assign]
    t = Tester(link, 1, "rprs", team=(0, 1))
    try:
        rep, stopped = t.run(), None
    except ConformanceError as exc:
        rep, stopped = t.report, str(exc)
    why = _table(rep, stopped, link)
    assert stopped is None and rep.passed, why
    assert "to our 99 and 00" in _figure(rep, "45"), why
    # the broken frame, then the same message whole (later clauses send theirs too)
    assert copies[0][7:8] == b"x" and copies[1] == copies[0][:7] + b"2" + copies[0][8:], why


def test_a_kit_waiting_for_an_answer_says_so_while_it_waits():
    """A robot that never answers (here: deaf, a lone claimer for ever) had the kit silent
    for the 50 s of its 400 invitations, without a line even without --quiet; it now says
    it invites, and again every 10 s."""
    lines: list[str] = []
    link = SimLink(1, "rprs", (0, 1), patch=lambda st, child: setattr(st.mac, "on_frame",
                                                                       lambda *a, **k: []))
    t = Tester(link, 1, "rprs", team=(0, 1), progress=lines.append)
    with pytest.raises(ConformanceError, match="answering our invitations"):
        t.run()
    assert lines[0].startswith("inviting robot 1 (poll(1,1) in our lone turns, up to 400)")
    still = [x for x in lines if x.startswith("still inviting robot 1:")]
    assert len(still) >= 3 and "no answer yet" in still[0]
