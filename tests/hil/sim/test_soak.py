"""A short soak in the test suite (the docs record a long one): random faults of every kind
and traffic, then the guarantees of docs/guarantees.md."""
from __future__ import annotations

import json
import random

import pytest

from firmware_model.timing import TICK_HZ, s_to_ticks
from hil.cli import main
from hil.sim.faults import parse_fault
from hil.sim.soak import random_faults, run_soak


@pytest.mark.slow
def test_short_soak_keeps_every_guarantee():
    r = run_soak(0.25, seed=3, checksum=True)
    assert sum(r.faults.values()) >= 10
    assert r.summary["submitted"] > 500
    failed = {k: v for k, v in r.invariants.items() if not v}
    assert not failed, (failed, r.summary["pending"], r.reform_s, r.not_reformed)


def test_a_three_minute_soak_with_dense_faults_keeps_every_guarantee():
    """The fast tier's sample of the soak above (slow tier): a fifth of its length, with
    faults about every 5 s instead of every 60 s, so it meets about as many."""
    schedule = random_faults(random.Random(3), (0, 1, 2, 3, 4), 0.05, True, True,
                             mean_gap_s=5.0)
    r = run_soak(0.05, seed=3, checksum=True, faults=schedule)
    assert sum(r.faults.values()) >= 10, r.faults
    assert len(r.faults) >= 5, r.faults                  # of several kinds
    assert r.summary["submitted"] > 400
    failed = {k: v for k, v in r.invariants.items() if not v}
    assert not failed, (failed, r.summary["pending"], r.reform_s, r.not_reformed)


@pytest.mark.parametrize("faults", [pytest.param(False, marks=pytest.mark.slow), True],
                         ids=["traffic", "CAN faults"])
def test_a_soak_is_the_same_run_whether_its_can_sides_sleep_or_not(faults):
    """Sleeping CAN sides (hil/sim/quiet_can.py: idle, and with cruising wheels) across the
    soak's steps, which do not wake them: the same accounting, faults and re-formations; with
    faults every 8 s or so too (a bus-off, silent nodes, a stalled wheel, noise, BER)."""
    schedule = random_faults(random.Random(3), (0, 1, 2, 3, 4), 0.05, True, True,
                             mean_gap_s=8.0) if faults else None
    if faults:
        assert {"busoff", "silent", "stall"} <= {f.kind for f in schedule}
    a, b = (vars(run_soak(0.05, seed=3, can_sleep=s, faults=schedule)).copy()
            for s in (False, True))
    a.pop("wall_s"), b.pop("wall_s")
    assert a.pop("can_periods_skipped") == 0.0 and b.pop("can_periods_skipped") > 0.2
    assert a["summary"]["submitted"] > 100 and a["summary"]["can_frames"] > 40_000
    assert a == b


def test_fault_schedule_is_seeded_and_round_trips():
    a = random_faults(random.Random("1"), (0, 1, 2, 3), 1.0, True, True)
    b = random_faults(random.Random("1"), (0, 1, 2, 3), 1.0, True, True)
    assert a == b and len(a) > 20
    for f in a:
        g = parse_fault(f.spec())
        assert g.kind == f.kind and g.robot == f.robot and g.node == f.node
        assert abs(g.at - f.at) < 1e-6 and (g.until is None) == (f.until is None)


def test_soak_command_json(capsys):
    assert main(["soak", "--hours", "0.05", "--seed", "2", "--no-can", "--json"]) == 0
    import json
    out = json.loads(capsys.readouterr().out)
    assert out[0]["checksum"] and all(out[0]["invariants"].values())


def test_soak_writes_the_trace_of_its_run(tmp_path, capsys):
    """``rprs soak --trace FILE``: an outside checker reads the run itself (its meta line, its
    faults, every delivery) instead of rebuilding the soak's configuration; the trace says
    what the summary counts. Two runs (``--checksum both``) are refused, and nothing is
    written."""
    path = tmp_path / "soak.jsonl"
    assert main(["soak", "--hours", "0.05", "--seed", "2", "--no-can", "--json", "--trace",
                 str(path)]) == 0
    summary = json.loads(capsys.readouterr().out)[0]["summary"]
    evs = [json.loads(line) for line in path.read_text().splitlines()]
    assert evs[0]["ev"] == "meta" and evs[0]["seed"] == 2 and evs[0]["robots"] == [0, 1, 2, 3, 4]
    # (a frame's event comes at its end: one may still be on air when the run ends)
    assert summary["occupations"] - sum(e["ev"] == "frame" for e in evs) in (0, 1)
    assert sum(e["ev"] == "submit" for e in evs) == summary["submitted"]
    assert sum(e["ev"] == "delivered" for e in evs) == summary["delivered"]
    assert {e["kind"] for e in evs if e["ev"] == "fault"}
    other = tmp_path / "both.jsonl"
    assert main(["soak", "--hours", "0.05", "--checksum", "both", "--trace", str(other)]) == 2
    assert "--checksum both makes two" in capsys.readouterr().err
    assert not other.exists()


def _stepwise(w, faults) -> tuple[list[float], int]:
    """The re-formation timer as it was first written: the world run in steps of SAMPLE_S,
    the ring checked at every step after a fault ends with no other active (from the last
    end, when a fault began meanwhile)."""
    from hil.sim.soak import REFORM_BOUND_S, SAMPLE_S
    ends = sorted({round(f.end, 6) for f in faults if f.kind != "skew"})
    starts = [(f.at, f.end) for f in faults]
    reform, not_reformed, pending, i = [], 0, None, 0
    while w.now < w.end_tick:
        w._advance(w.now + s_to_ticks(SAMPLE_S))
        now_s = w.now / TICK_HZ
        while i < len(ends) and ends[i] <= now_s:
            if not any(a <= now_s < e for a, e in starts):
                pending = ends[i] if pending is None else pending
            i += 1
        if pending is not None and any(pending < a <= now_s for a, _ in starts):
            active = any(a <= now_s < e for a, e in starts)
            pending = None if active else max(e for _, e in starts if e <= now_s)
        if pending is not None:
            if w.ring_complete():
                reform.append(round(now_s - pending, 3))
                pending = None
            elif now_s - pending > 4 * REFORM_BOUND_S:
                not_reformed += 1
                pending = None
    if pending is not None and not w.ring_complete():
        not_reformed += 1
    return reform, not_reformed


@pytest.mark.parametrize("spec", [
    pytest.param(("fail:2@12", "recover:2@20.1"), marks=pytest.mark.slow),
    ("fail:0@7.3", "recover:0@9", "ber@30-31:0.01", "steal:1@44.4"),
    pytest.param((), marks=pytest.mark.slow),
])
def test_reformations_timed_in_long_steps_are_the_same(spec):
    """The re-formation timer runs the world in one go between the fault ends it must see
    (so that an idle ring can leap over its cycles), with a progress callback too (then in
    runs of a hundredth of the soak at most): the same re-formation times, the same run, as
    step by step."""
    from hil.sim.soak import run_timing_reformations
    from hil.sim.world import SimConfig, World
    faults = tuple(parse_fault(x) for x in spec)
    cfg = SimConfig(robots=(0, 1, 2, 3), duration=80, seed=5, faults=faults)
    stepped, shown, whole = World(cfg), World(cfg), World(cfg)
    calls = []
    want = _stepwise(stepped, faults)
    assert run_timing_reformations(shown, faults, progress=calls.append) == want
    assert run_timing_reformations(whole, faults) == want
    assert stepped.summary() == shown.summary() == whole.summary()
    assert 100 <= len(calls) <= 320 and calls == sorted(calls) and calls[-1] == 80.0
    assert max(b - a for a, b in zip([0.0] + calls, calls)) <= 0.8 + 1e-9
    assert whole.quiet_ring.ticks_skipped > stepped.quiet_ring.ticks_skipped
    if faults:
        assert want[1] == 0 and len(want[0]) >= 1


def test_step_seeing_lands_on_the_first_sample_past_a_fault_end():
    from firmware_model.timing import TICK_HZ
    from hil.sim.soak import SAMPLE_S, _step_seeing
    step = round(SAMPLE_S * TICK_HZ)
    assert _step_seeing(0, step, 20.1, 10**12) == round(20.25 * TICK_HZ)
    assert _step_seeing(0, step, 20.0, 10**12) == 20 * TICK_HZ
    assert _step_seeing(step, step, 0.1, 10**12) == 2 * step      # at least one step
    assert _step_seeing(0, step, None, 99) == 99
    assert _step_seeing(0, step, 50.0, 7 * step) == 7 * step


def test_both_checksum_settings_side_by_side_are_the_runs_one_after_the_other():
    """``rprs soak --checksum both`` runs the two soaks in two processes at once: the same
    results, in the same order, as one after the other (only the wall time differs); the
    progress of each is reported under its own index."""
    from hil.sim.soak import run_soaks
    seen: dict[int, float] = {}
    apart = run_soaks(0.05, 3, [True, False], parallel=True, can=False,
                      progress=lambda i, s: seen.__setitem__(i, max(s, seen.get(i, 0.0))))
    serial = run_soaks(0.05, 3, [True, False], parallel=False, can=False)
    for r in apart + serial:
        r.wall_s = 0.0
    assert apart == serial
    assert [r.checksum for r in apart] == [True, False]
    assert apart[0].summary != apart[1].summary          # two different runs
    assert set(seen) <= {0, 1} and all(0.0 <= s <= 180.0 for s in seen.values())


def test_a_soak_process_that_fails_is_an_error_not_a_hang():
    from hil.sim.soak import run_soaks
    with pytest.raises(ValueError, match="at least"):
        run_soaks(0.001, 3, [True, False], parallel=True, can=False)


def test_stop_signals_wait_while_the_soak_processes_fork(monkeypatch, tmp_path):
    """SIGTERM to the group just as ``rprs soak --checksum both`` forked reached a child
    before it had set its own handlers: it ran the parent's, which raises, inside the fork's
    bookkeeping, and stderr got "Exception ignored in: <function _after_fork>" and a
    traceback (the README's loop saw it once). The parent now holds SIGINT and SIGTERM while
    it forks: each child starts with them blocked (and unblocks them once its handlers are
    set), and the parent's own mask is back as it was afterwards."""
    import signal

    import hil.sim.soak as soak

    def spy(conn, done, hours, seed, checksum, kw):
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, [])       # (reads the mask)
        (tmp_path / f"mask-{checksum}").write_text(" ".join(str(int(s)) for s in mask))
        conn.send(ValueError("spy"))
        conn.close()
    monkeypatch.setattr(soak, "_soak_child", spy)
    before = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    with pytest.raises(ValueError, match="spy"):
        soak.run_soaks(0.05, 3, [True, False], parallel=True, can=False)
    for checksum in (True, False):
        held = {int(x) for x in (tmp_path / f"mask-{checksum}").read_text().split()}
        assert {int(signal.SIGINT), int(signal.SIGTERM)} <= held, held
    assert signal.pthread_sigmask(signal.SIG_BLOCK, []) == before


@pytest.mark.parametrize("signame,status,said", [("SIGINT", 130, "rprs: interrupted"),
                                                 ("SIGTERM", 143, "rprs: terminated")])
def test_ctrl_c_stops_both_soaks_and_leaves_no_process(signame, status, said):
    """Ctrl-C (SIGINT to the terminal's process group) or SIGTERM to the group (``kill``,
    ``timeout``) during ``--checksum both``: the parent stops its two soak processes and
    exits with one line; nothing keeps running."""
    import os
    import signal
    import subprocess
    import sys
    import time
    p = subprocess.Popen([sys.executable, "-m", "hil.cli", "soak", "--hours", "0.3", "--seed",
                          "1", "--checksum", "both", "--no-can"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:            # both soak processes started
            kids = subprocess.run(["pgrep", "-P", str(p.pid)], capture_output=True,
                                  text=True).stdout.split()
            if len(kids) == 2:
                break
            time.sleep(0.1)
        assert len(kids) == 2, kids
        os.killpg(p.pid, getattr(signal, signame))
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == status and err.strip() == said, err[-500:]
    for k in kids:
        assert not os.path.exists(f"/proc/{k}") or \
            open(f"/proc/{k}/status").read().split("State:")[1].split()[0] == "Z"


@pytest.mark.parametrize("mode", ["off", "on"])
def test_a_soak_that_breaks_a_promise_fails_with_the_checksum_off_too(monkeypatch, capsys,
                                                                     mode):
    """The exit status judged only the runs with the checksum, so ``--checksum off`` exited 0
    whatever broke, a ring that never re-formed too. Without the checksum a soak still judges
    what is promised without it (docs/guarantees.md): every message ended, nothing to the
    wrong robot, the ring re-formed; not "nothing twice" nor "no corrupted command"."""
    import hil.sim.soak as soak
    real = soak.run_soak

    def broken(*args, **kw):
        r = real(*args, **kw)
        r.not_reformed = 1
        return r
    monkeypatch.setattr(soak, "run_soak", broken)
    assert main(["soak", "--hours", "0.05", "--seed", "2", "--no-can", "--checksum",
                 mode]) == 1
    assert "| **ring re-formed within 15 s of every fault** | **NO** |" in \
        capsys.readouterr().out

    def corrupted(*args, **kw):
        r = real(*args, **kw)
        r.summary["corrupt_deliveries"] = 1        # not promised without the checksum
        return r
    monkeypatch.setattr(soak, "run_soak", corrupted)
    assert main(["soak", "--hours", "0.05", "--seed", "2", "--no-can", "--checksum",
                 mode]) == (0 if mode == "off" else 1)


def _fake_result(checksum: bool, duplicates: int = 0, pending: int = 0):
    """A soak's result without running one: the counts ``report`` and the exit status read."""
    from hil.sim.soak import SoakResult
    summary = {"occupations": 100, "collisions": 0, "robots": {1: {"missed": 0,
               "refused_frames": 0}}, "membership_changes": [], "submitted": 10,
               "delivered": 10 - pending, "failed": 0, "pending": pending,
               "duplicate_deliveries": duplicates, "wrong_robot_deliveries": 0,
               "corrupt_deliveries": 0, "oldest_outcome_s": 3.0}
    return SoakResult(hours=0.05, seed=1, checksum=checksum, faults={"ber": 1},
                      summary=summary, reform_s=[0.1])


@pytest.mark.parametrize("duplicates_on, duplicates_off, pending_off, status", [
    (0, 1, 0, 0),       # checksum off delivers twice: expected, not a broken promise
    (1, 0, 0, 1),       # checksum on delivers twice: a broken promise
    (0, 1, 2, 1),       # checksum off leaves messages pending: promised with or without
    (0, 0, 0, 0),       # every invariant holds: no legend of the noes under the table
])
def test_the_soak_says_which_no_is_a_broken_promise(monkeypatch, capsys, duplicates_on,
                                                    duplicates_off, pending_off, status):
    """``rprs soak --checksum both`` printed a bold **NO** for "nothing delivered twice"
    without the checksum and exited 0, saying nowhere that this no is expected there. A no
    that no promise covers now says so, a broken promise alone is a bold **NO**, a last row
    says whether every promise held, and the exit status follows that row only. The legend
    of the noes ("Key: a bold **NO** would mark a broken promise...") is printed only where a no
    is shown: under a table of yeses it read like an alarm."""
    import hil.sim.soak as soak
    results = [_fake_result(True, duplicates_on), _fake_result(False, duplicates_off,
                                                               pending_off)]
    monkeypatch.setattr(soak, "run_soaks", lambda *a, **kw: results)
    assert main(["soak", "--hours", "0.05", "--checksum", "both", "--no-can"]) == status
    out = capsys.readouterr().out
    twice = next(x for x in out.splitlines() if x.startswith("| **nothing delivered twice**"))
    on, off = twice.split("|")[2:4]
    assert on.strip() == ("**NO**" if duplicates_on else "yes")
    assert off.strip() == ("no (not promised without the checksum)" if duplicates_off
                           else "yes")
    kept = next(x for x in out.splitlines() if x.startswith("| **every promise kept**"))
    assert [c.strip() for c in kept.split("|")[2:4]] == \
        ["**NO**" if duplicates_on else "yes", "**NO**" if pending_off else "yes"]
    noes = duplicates_on + duplicates_off + pending_off
    assert out.count("**NO**") == (duplicates_on + bool(pending_off)) * 2 + bool(noes)
    assert ("a no there is expected and leaves the exit status 0" in out) == bool(noes)

    monkeypatch.setattr(soak, "run_soaks", lambda *a, **kw: results)
    assert main(["soak", "--hours", "0.05", "--checksum", "both", "--no-can", "--json"]) \
        == status
    runs = json.loads(capsys.readouterr().out)
    assert [r["kept"] for r in runs] == [not duplicates_on, not pending_off]
    assert runs[1]["promised"]["nothing delivered twice"] is False
    assert runs[0]["promised"]["nothing delivered twice"] is True


def test_even_the_shortest_soak_injects_a_fault():
    """``rprs soak --hours 0.05 --seed 3`` injected no fault (47 seeds of 100 drew none in its
    50 s window) and still reported every promise kept. A schedule has one at least, the
    same for the same seed."""
    import random

    from hil.sim.soak import MIN_HOURS, SETTLE_S, random_faults
    for seed in range(100):
        faults = random_faults(random.Random(seed), (0, 1, 2, 3), MIN_HOURS, False, False)
        assert faults and all(SETTLE_S <= f.at < MIN_HOURS * 3600 for f in faults), seed
        again = random_faults(random.Random(seed), (0, 1, 2, 3), MIN_HOURS, False, False)
        assert again == faults


def test_a_message_older_than_max_age_at_its_end_is_a_broken_promise():
    """The soak checked only that every message ended: seed 39 (ideal CPU, no CAN side) had a
    standby PC's held messages fail 145 s after submission, and every promise was "kept"."""
    ok = _fake_result(True)
    assert ok.kept
    late = _fake_result(True)
    late.summary["oldest_outcome_s"] = 145.0
    name = next(k for k in late.invariants if k.startswith("every message ended within 60 s"))
    assert not late.invariants[name] and not late.kept


def test_a_burst_and_a_foreign_transmitter_end_when_their_bytes_leave_the_air():
    """The soak timed a burst's re-formation from the burst's start, and took it for over
    while it still jammed the air: a fault ends when it stops acting."""
    assert parse_fault("burst@3:0.5").end == 3.5
    assert parse_fault("foreign@2:x0f0a05").end == pytest.approx(2 + 3 * 16667 / TICK_HZ)
    assert parse_fault("foreign@2:96").end == pytest.approx(2 + 96 * 16667 / TICK_HZ)
    assert parse_fault("steal:1@4").end == 4.0
    assert parse_fault("ber@30-31:0.01").end == 31.0


def test_a_robot_dropped_with_no_radio_fault_near_is_a_broken_promise():
    """The soak looked at the ring once after each fault: a healthy robot dropped later, with
    no radio fault acting or just over, passed. A drop counts unless a radio fault acted
    within REFORM_BOUND_S before it (a CAN fault stays inside its child)."""
    from hil.sim.soak import REFORM_BOUND_S, unexplained_drops

    def drop(s: float, robot: int = 2) -> tuple[int, str, int]:
        return (s_to_ticks(s), "disable", robot)

    faults = [parse_fault(f) for f in ("fail:2@20", "recover:2@25", "burst@100:0.5",
                                       "busoff:3@200", "stuck:1@300-302")]
    membership = [drop(5.0),                          # the ring forming: not counted
                  drop(22.0), (s_to_ticks(26.0), "join", 2),
                  drop(25 + REFORM_BOUND_S),          # the last tick of the window
                  drop(100.5 + REFORM_BOUND_S - 0.01, 4),   # after the burst's bytes
                  drop(100.5 + REFORM_BOUND_S + 0.1, 4),
                  drop(201.0, 3), drop(301.0, 1), drop(400.0)]
    assert unexplained_drops(membership, faults) == [
        (round(100.5 + REFORM_BOUND_S + 0.1, 3), 4), (201.0, 3), (301.0, 1), (400.0, 2)]
    # a robot whose clock runs slow upsets the ring all the run
    assert unexplained_drops(membership, faults + [parse_fault("skew:4:0.06")]) == []
    ok = _fake_result(True)
    assert ok.kept
    ok.unexplained_drops = [(400.0, 2)]
    name = next(k for k in ok.invariants if k.startswith("no robot dropped"))
    assert not ok.invariants[name] and not ok.kept


class _RingBrokenBetween:
    """What ``run_timing_reformations`` reads of a world: a ring not whole from ``a`` to
    ``b`` seconds of a 60 s run."""

    def __init__(self, a: float, b: float) -> None:
        self.a, self.b = a, b
        self.now = 0
        self.end_tick = s_to_ticks(60)

    def _advance(self, until: int) -> None:
        self.now = until

    def ring_complete(self) -> bool:
        return not self.a <= self.now / TICK_HZ < self.b


@pytest.mark.parametrize("specs, reform", [
    (("fail:2@12",), [7.0]),                         # whole again 7 s after the fault
    (("fail:2@12", "noise@14-16"), [3.0]),           # timed from the noise's end
    (("fail:2@12", "noise@14-16", "steal:1@18"), [1.0]),
    (("fail:2@12", "steal:1@20"), [7.0, 0.0]),       # a fault after the ring re-formed
])
def test_a_reformation_is_timed_from_the_last_fault_that_began_before_it(specs, reform):
    """A fault that began while the ring was not yet whole again after another restarts the
    time: the 15 s promise is about the ring after the faults. Timed from the first, a
    robot's failure followed by 13 s of noise would count the noise against the ring."""
    from hil.sim.soak import run_timing_reformations
    faults = [parse_fault(s) for s in specs]
    assert run_timing_reformations(_RingBrokenBetween(12.0, 19.0), faults) == (reform, 0)
