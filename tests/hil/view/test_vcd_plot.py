"""VCD waveform (hil.view.vcd) and Fig. 7 plot (hil.view.plot) from simulated traces."""
from __future__ import annotations

import io
import json
import shutil
import subprocess

import pytest

pytest.importorskip("vcd")
pytest.importorskip("matplotlib")

from vcd.reader import TokenKind, tokenize  # noqa: E402

from hil.view.plot import PlotError, plot_trace  # noqa: E402
from hil.sim.events import typed  # noqa: E402
from hil.sim.trace import TraceError, TraceWriter, read_trace  # noqa: E402
from hil.view.vcd import VcdError, VcdTraceWriter, timescale_for, write_vcd  # noqa: E402
from hil.sim.world import Fault, SimConfig, World  # noqa: E402

UNITS = 625          # 100 ps units per 62.5 ns tick


def _sim(**kw) -> list[dict]:
    evs: list[dict] = []
    World(SimConfig(**kw), on_event=evs.append).run()
    return evs


@pytest.fixture(scope="module")
def fault_run() -> list[dict]:
    """The paper's scenario with CAN: R1's radio dies at 8 s (3 misses, dropped), comes back
    at 14.9 s (a collision, then a rejoin at 15.26 s: the seeded orders' timing decides
    whether a recovery meets a frame; at 15.0 s, with the dispatcher's rules for a joint
    still moving, it meets none)."""
    return _sim(robots=(1, 2, 3, 4), duration=20.0, load=1.0, can=True,
                faults=(Fault("fail", 1, 8.0), Fault("recover", 1, 14.9)))


@pytest.fixture(scope="module")
def idle_run() -> list[dict]:
    return _sim(robots=(1, 2, 3), duration=4.0)


def parse_vcd(path) -> tuple[dict, dict[str, list[tuple[int, object]]], dict]:
    """Header keywords, {scope.name: [(time, value)]} and {scope.name: VarDecl}."""
    with open(path, "rb") as f:
        data = f.read()
    header: dict = {}
    names: dict[str, str] = {}
    decls: dict = {}
    scope: list[str] = []
    changes: dict[str, list[tuple[int, object]]] = {}
    now = 0
    for tok in tokenize(io.BytesIO(data)):
        k = tok.kind
        if k is TokenKind.TIMESCALE:
            mag = tok.timescale.magnitude
            header["timescale"] = f"{getattr(mag, 'value', mag)} {tok.timescale.unit.value}"
        elif k is TokenKind.SCOPE:
            scope.append(tok.scope.ident)
        elif k is TokenKind.UPSCOPE:
            scope.pop()
        elif k is TokenKind.VAR:
            full = ".".join(scope + [tok.var.reference])
            names[tok.var.id_code] = full
            decls[full] = tok.var
            changes[full] = []
        elif k is TokenKind.CHANGE_TIME:
            now = tok.time_change
        elif k in (TokenKind.CHANGE_SCALAR, TokenKind.CHANGE_VECTOR):
            ch = tok.scalar_change if k is TokenKind.CHANGE_SCALAR else tok.vector_change
            changes[names[ch.id_code]].append((now, ch.value))
    return header, changes, decls


def value_at(changes, name, time):
    """Value of a signal just after all changes at ``time``."""
    v = None
    for t, val in changes[name]:
        if t > time:
            break
        v = val
    return v


def frames(evs):
    return [e for e in evs if e["ev"] == "frame"]


# -- VCD -------------------------------------------------------------------------------------

def heard_misses(evs) -> set[tuple[int, int]]:
    """(robot, tick) of each miss reported by a robot whose radio worked (the summary's
    count: a deaf robot blames the others for its own silence)."""
    deaf: set[int] = set()
    out = set()
    for e in evs:
        if e["ev"] == "fault" and e.get("kind") in ("fail", "recover"):
            (deaf.add if (e["kind"] == "fail") == (e.get("phase") != "end")
             else deaf.discard)(e["robot"])
        elif e["ev"] == "miss" and e["by"] not in deaf:
            out.add((e["robot"], e["t"]))
    return out


def test_timescale_maps_ticks_exactly():
    assert timescale_for(16_000_000) == ("100 ps", 625)
    assert timescale_for(1_000_000) == ("1 us", 1)


def test_vcd_header_and_signals(fault_run, tmp_path):
    out = tmp_path / "run.vcd"
    s = write_vcd(fault_run, str(out))
    assert s["timescale"] == "100 ps" and s["units_per_tick"] == UNITS
    assert s["frames"] == len(frames(fault_run))
    header, ch, decls = parse_vcd(out)
    assert header["timescale"] == "100 ps"
    for r in (1, 2, 3, 4):
        for sig in ("txen", "tx", "rx", "miss"):
            assert f"rprs.R{r}.{sig}" in ch
        assert decls[f"rprs.can_{r}"].size == 11
    assert decls["rprs.owner"].size == 3 and "rprs.collision" in ch
    assert not list(tmp_path.glob("*.partial"))


def test_vcd_tx_rx_owner_follow_the_frames(fault_run, tmp_path):
    out = tmp_path / "run.vcd"
    write_vcd(fault_run, str(out))
    _, ch, _ = parse_vcd(out)
    f1 = next(f for f in frames(fault_run) if f["src"] == 1 and not f["collided"])
    s, e = f1["start"] * UNITS, f1["end"] * UNITS
    assert (s, "1") in ch["rprs.R1.tx"] and (e, "0") in ch["rprs.R1.tx"]
    assert value_at(ch, "rprs.R1.tx", s - 1) == "0"
    assert value_at(ch, "rprs.R1.tx", s) == "1"
    assert value_at(ch, "rprs.R2.rx", s) == "1" and value_at(ch, "rprs.R2.rx", e) == "0"
    assert value_at(ch, "rprs.R1.rx", s) == "0"
    # owner: the source of each clean frame from its first bit, held after its End
    clean = [f for f in frames(fault_run) if not f["collided"]][:40]
    for f in clean:
        assert value_at(ch, "rprs.owner", f["start"] * UNITS) == f["src"]
        assert value_at(ch, "rprs.owner", f["end"] * UNITS) == f["src"]
    owners = [v for _, v in ch["rprs.owner"]]
    assert {1, 2, 3, 4} <= set(owners)
    # txen rises Ttrans before the frame's first bit
    assert value_at(ch, "rprs.R1.txen", s - 80_000 * UNITS) == "1"


def test_the_standby_pcs_frames_have_a_signal_of_their_own(tmp_path):
    """PC1's and PC2's frames were one signal, ``R0.tx``: a failover could not be seen in
    the waveform. ``R0.tx`` is PC1's, ``R0.pc2_tx`` PC2's, each following its frames."""
    evs = _sim(robots=(0, 1, 2), duration=12.0, father_standby=True,
               faults=(Fault("fail", 0, 4.0), Fault("recover", 0, 8.0)))
    out = tmp_path / "pair.vcd"
    write_vcd(evs, str(out))
    _, ch, decls = parse_vcd(out)
    assert "rprs.R0.pc2_tx" in decls
    by_pc2 = [f for f in frames(evs) if f["src"] == 0 and f.get("pc") == 2 and
              not f["collided"]]
    by_pc1 = [f for f in frames(evs) if f["src"] == 0 and f.get("pc") != 2 and
              not f["collided"]]
    assert by_pc1 and by_pc2
    for f in by_pc2[:5] + by_pc2[-3:]:
        assert value_at(ch, "rprs.R0.pc2_tx", f["start"] * UNITS) == "1"
        assert value_at(ch, "rprs.R0.tx", f["start"] * UNITS) == "0"
    for f in by_pc1[:5] + by_pc1[-3:]:
        assert value_at(ch, "rprs.R0.tx", f["start"] * UNITS) == "1"
        assert value_at(ch, "rprs.R0.pc2_tx", f["start"] * UNITS) == "0"


def test_vcd_shows_the_collision(fault_run, tmp_path):
    out = tmp_path / "run.vcd"
    s = write_vcd(fault_run, str(out))
    _, ch, _ = parse_vcd(out)
    col = next(e for e in fault_run if e["ev"] == "collision")
    both = [f for f in frames(fault_run) if f["collided"]]
    assert s["collided_frames"] == len(both) == 2
    t = col["t"] * UNITS
    assert value_at(ch, "rprs.collision", t - 1) == "0"
    assert value_at(ch, "rprs.collision", t) == "1"
    assert value_at(ch, "rprs.owner", t) == "x"
    bystander = ({1, 2, 3, 4} - set(col["robots"])).pop()
    assert value_at(ch, f"rprs.R{bystander}.rx", t) == "x"
    overlap_end = min(f["end"] for f in both) * UNITS
    assert value_at(ch, "rprs.collision", overlap_end) == "0"


def test_vcd_misses_deduplicated_and_dead_radio_is_z(fault_run, tmp_path):
    out = tmp_path / "run.vcd"
    s = write_vcd(fault_run, str(out))
    _, ch, _ = parse_vcd(out)
    misses = heard_misses(fault_run)
    assert s["misses"] == len(misses) < sum(e["ev"] == "miss" for e in fault_run)
    assert {r for r, _ in misses} == {1}       # R1's reports of the others, deaf, are none
    r1 = sorted(t for r, t in misses if r == 1)
    assert [t for t, _ in ch["rprs.R1.miss"]] == [t * UNITS for t in r1]
    assert value_at(ch, "rprs.R1.rx", 10 * 16_000_000 * UNITS) == "z"   # failed 8 s .. 14 s
    assert value_at(ch, "rprs.R1.rx", 8 * 16_000_000 * UNITS - 1) != "z"


def test_vcd_can_ids(fault_run, tmp_path):
    out = tmp_path / "run.vcd"
    s = write_vcd(fault_run, str(out))
    _, ch, _ = parse_vcd(out)
    cans = [e for e in fault_run if e["ev"] == "can" and e["bus"] == 3]
    assert s["can_frames"] == sum(e["ev"] == "can" for e in fault_run)
    for c in cans[:20]:
        assert value_at(ch, "rprs.can_3", c["start"] * UNITS) == c["id"]
        assert value_at(ch, "rprs.can_3", c["end"] * UNITS) == "z"
    assert len({c["id"] for c in cans}) > 1


def test_vcd_is_deterministic_and_streams(fault_run, tmp_path):
    a, b = tmp_path / "a.vcd", tmp_path / "b.vcd"
    write_vcd(fault_run, str(a))
    w = VcdTraceWriter(str(b))            # as World(listeners=[w.write]) uses it
    for ev in typed(fault_run):
        w.write(ev)
    w.close()
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.skipif(shutil.which("vcd2fst") is None, reason="GTKWave's vcd2fst not installed")
def test_gtkwave_reads_the_vcd(fault_run, tmp_path):
    out = tmp_path / "run.vcd"
    write_vcd(fault_run, str(out))
    r = subprocess.run(["vcd2fst", str(out), str(tmp_path / "run.fst")], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "run.fst").stat().st_size > 1000


def test_vcd_from_a_trace_file(idle_run, tmp_path):
    tr = tmp_path / "t.jsonl"
    w = TraceWriter(str(tr))
    for ev in typed(idle_run):
        w.write(ev)
    w.close()
    s = write_vcd(read_trace(str(tr)), str(tmp_path / "t.vcd"))
    assert s["robots"] == [1, 2, 3] and s["can_frames"] == 0


def _bad_traces(evs):
    meta, rest = evs[0], evs[1:200]
    last = rest[-1]["t"]
    frame = next(e for e in rest if e["ev"] == "frame")
    d = frame["end"] - frame["start"]
    broken = {**frame, "t": last}
    del broken["start"]
    yield [], "empty trace"
    yield rest, "meta"
    yield [meta] + rest + [broken], "missing 'start'"
    yield [meta] + rest + [dict(rest[5], t=0)], "out of order"
    yield [meta] + rest + [{**frame, "t": last, "start": last - d, "end": last, "src": 6}], \
        "not in the ring"
    yield [meta] + rest + [{**frame, "t": last, "end": last, "start": last + 1}], \
        "after end"
    late = last + 10**9                 # a frame lasting 62 s: cannot be reordered
    yield [meta] + rest + [{"t": late, "ev": "power", "robot": 1},
                           {**frame, "t": late, "end": late}], "before the event"


def test_bad_trace_raises_and_leaves_no_file(idle_run, tmp_path):
    out = tmp_path / "bad.vcd"
    for evs, msg in _bad_traces(idle_run):
        with pytest.raises(TraceError, match=msg):
            write_vcd(evs, str(out))
        assert list(tmp_path.iterdir()) == []
    out.write_text("old")                 # a previous complete file stays as it was
    with pytest.raises(TraceError):
        write_vcd(idle_run[:50] + [{"ev": "frame", "t": 10**9}], str(out))
    assert out.read_text() == "old" and list(tmp_path.iterdir()) == [out]


def test_unwritable_vcd_path(idle_run, tmp_path):
    with pytest.raises(VcdError, match="cannot write VCD"):
        write_vcd(idle_run, str(tmp_path / "no" / "such" / "dir.vcd"))


# -- plot ------------------------------------------------------------------------------------

def test_plot_png_default_window_around_the_first_fault(fault_run, tmp_path):
    out = tmp_path / "fig7.png"
    s = plot_trace(fault_run, str(out))
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 30_000
    assert s["format"] == "png" and 0 < s["turns"] <= 200
    lo, hi = s["window_s"]
    assert lo < 8.0 < hi                   # the radio failure, its misses and the disable
    assert s["misses"] == len(heard_misses(fault_run)) == 3
    assert s["disables"] == 1 and s["rejoins"] == 1 and s["collided"] == 2
    assert 0.5 < s["utilisation"] < 0.9
    assert not list(tmp_path.glob("*.partial"))


def test_on_the_cpu_model_a_miss_and_a_drop_are_drawn_and_counted_once(tmp_path):
    """On the CPU model (the command line's default) the members report a miss or a drop a
    tick or a handler apart: ``rprs plot`` counted 9 misses for 6 and drew "R1 disabled"
    twice, the VCD had a miss event per report tick. Both now count as the run's summary
    does (reports within half of Tmax are one), the same as on the ideal CPU."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    runs = {}
    for cpu in (None, DEFAULT_COSTS):
        evs = _sim(robots=(1, 2, 3, 4), duration=20.0, load=1.0, seed=3, cpu=cpu,
                   faults=(Fault("fail", 1, 8.0), Fault("recover", 1, 15.0)))
        ticks = {e["t"] for e in evs if e["ev"] == "disable"}
        runs[cpu is None] = (plot_trace(evs, str(tmp_path / "f.svg")),
                             write_vcd(evs, str(tmp_path / "r.vcd")), len(ticks))
    (ideal, ideal_vcd, _), (model, model_vcd, disable_ticks) = runs[True], runs[False]
    assert disable_ticks > 1                   # the reports of the drop: several ticks
    assert model["disables"] == ideal["disables"] == 1
    assert model["misses"] == ideal["misses"] == model_vcd["misses"] == ideal_vcd["misses"]
    assert model["misses"] == 3       # R1's; those R1 reported of the others while deaf: none


def test_plot_svg_with_window(fault_run, tmp_path):
    out = tmp_path / "fig7.svg"
    s = plot_trace(fault_run, str(out), start_s=14.9, end_s=15.6)
    text = out.read_text()
    assert "<svg" in text[:2000]
    for r in (1, 2, 3, 4):
        assert f"R{r}" in text
    assert "collided frame" in text and "R1 rejoins" in text
    assert s["window_s"] == [14.9, 15.6] and s["turns"] > 10
    again = tmp_path / "again.svg"
    plot_trace(fault_run, str(again), start_s=14.9, end_s=15.6)
    assert again.read_bytes() == out.read_bytes()      # reproducible


def test_the_zoom_is_one_cycle_inside_the_window_from_the_lowest_id(fault_run, tmp_path):
    # docs/visualisation.md, Fig. 7 item 2. With --start 14.9 the zoom began at R3 at
    # 14.892 s: a frame straddling the window's start, and a cycle that did not start at R1
    out = str(tmp_path / "z.png")
    for start in (14.85, 14.9, 14.95):
        s = plot_trace(fault_run, out, start_s=start, end_s=start + 0.7)
        lo, hi = s["zoom_s"]
        assert start <= lo < hi <= start + 0.7, (start, s["zoom_s"])
        ids = s["zoom_robots"]           # a robot's turn up to its next: one whole cycle
        assert ids[0] == ids[-1] == min(ids) and len(set(ids)) == len(ids) - 1, (start, ids)
    # 14.85: R1 is still out of the ring (R2 R3 R4), and a cycle from R2 ends before the
    # radio comes back; from 15.4 on R1 is back (invited at 15.26 s), and the cycle is from R1
    assert plot_trace(fault_run, out, start_s=14.85, end_s=15.55)["zoom_robots"] == [2, 3, 4, 2]
    s = plot_trace(fault_run, out, start_s=15.4, end_s=16.1)
    assert s["zoom_robots"] == [1, 2, 3, 4, 1] and s["zoom_s"][0] > 15.4
    s = plot_trace(fault_run, out)       # the default window: the last cycle before R1 fails
    assert s["zoom_robots"] == [1, 2, 3, 4, 1] and s["zoom_s"][1] <= 8.0


def test_plot_idle_ring_from_file(idle_run, tmp_path):
    tr = tmp_path / "t.jsonl"
    tr.write_text("".join(json.dumps(e) + "\n" for e in idle_run))
    s = plot_trace(read_trace(str(tr)), str(tmp_path / "idle.PNG"))
    assert s["misses"] == 0 and s["turns"] > 20
    assert (tmp_path / "idle.PNG").stat().st_size > 20_000


@pytest.mark.parametrize("name", ["fig.jpg", "fig.gif", "fig", "fig.png.txt"])
def test_plot_rejects_other_formats(idle_run, tmp_path, name):
    with pytest.raises(PlotError, match=r"\.png, \.svg or \.pdf"):
        plot_trace(idle_run, str(tmp_path / name))
    assert list(tmp_path.iterdir()) == []


def test_plot_bad_input(idle_run, tmp_path):
    out = tmp_path / "x.png"
    with pytest.raises(TraceError, match="empty trace"):
        plot_trace([], str(out))
    with pytest.raises(TraceError, match="no frame"):
        plot_trace(idle_run[:1], str(out))
    (tmp_path / "empty.jsonl").write_text("")
    with pytest.raises(TraceError, match="empty trace"):
        plot_trace(read_trace(str(tmp_path / "empty.jsonl")), str(out))
    with pytest.raises(TraceError, match="cannot read trace"):
        plot_trace(read_trace(str(tmp_path / "missing.jsonl")), str(out))
    (tmp_path / "junk.jsonl").write_text("this is not json\n")
    with pytest.raises(TraceError, match="not a JSON line"):
        plot_trace(read_trace(str(tmp_path / "junk.jsonl")), str(out))
    # another version's trace (a newer rprs's, a hand-edited one) was read without a word
    for version, says in ((2, "trace version 2: this rprs reads version 1 \\(a newer"),
                          (0, "trace version 0"), ('"1"', "trace version '1'"),
                          ("null", "trace version None")):
        f = tmp_path / "other.jsonl"
        f.write_text(json.dumps(idle_run[0]).replace('"version": 1', f'"version": {version}')
                     + "\n" + "".join(json.dumps(e) + "\n" for e in idle_run[1:50]))
        with pytest.raises(TraceError, match=says):
            plot_trace(read_trace(str(f)), str(out))
    assert not out.exists() and not list(tmp_path.glob("*.partial"))


def test_plot_reads_a_gzipped_trace(idle_run, tmp_path):
    """A trace compressed with gzip (told apart by its magic bytes, whatever its name)
    plots the same figure as the plain file."""
    import gzip
    text = "".join(json.dumps(e) + "\n" for e in idle_run)
    (tmp_path / "t.jsonl").write_text(text)
    (tmp_path / "t.jsonl.gz").write_bytes(gzip.compress(text.encode()))
    plain = plot_trace(read_trace(str(tmp_path / "t.jsonl")), str(tmp_path / "a.svg"))
    packed = plot_trace(read_trace(str(tmp_path / "t.jsonl.gz")), str(tmp_path / "b.svg"))
    plain.pop("path"), packed.pop("path")
    assert plain == packed and plain["turns"] > 20
    assert (tmp_path / "a.svg").read_bytes() == (tmp_path / "b.svg").read_bytes()


def test_the_same_trace_gives_the_same_svg_bytes_every_time(idle_run, tmp_path):
    """Matplotlib named clip paths after memory addresses: drawn again in the same process,
    the same figure differed in those names (a flake of the gzip test, run 2 of the 20-run
    loop). They are numbered in order now."""
    outs = []
    for i in range(4):
        plot_trace(idle_run, str(tmp_path / f"f{i}.svg"))
        outs.append((tmp_path / f"f{i}.svg").read_bytes())
    assert all(o == outs[0] for o in outs)
    assert b'clip-path="url(#clip1)"' in outs[0] and b'id="clip1"' in outs[0]


def test_plot_writes_a_pdf_the_same_every_time(idle_run, tmp_path):
    """``rprs plot -o x.pdf`` was refused although matplotlib writes PDF; it is written now,
    without a creation date, so the same trace gives the same bytes."""
    outs = []
    for i in range(2):
        info = plot_trace(idle_run, str(tmp_path / f"f{i}.pdf"))
        outs.append((tmp_path / f"f{i}.pdf").read_bytes())
    assert info["format"] == "pdf" and outs[0].startswith(b"%PDF-") and outs[0] == outs[1]


def test_plot_refuses_files_that_are_not_traces(idle_run, tmp_path):
    """An image, a text with non-ASCII bytes and a truncated gzip are refused with a
    TraceError naming the file (the CLI prints it as one line), never a UnicodeDecodeError."""
    import gzip
    out = tmp_path / "x.png"
    plot_trace(idle_run, str(out))
    text = "".join(json.dumps(e) + "\n" for e in idle_run).encode()
    (tmp_path / "notes.txt").write_bytes("# RPRS \u2014 notes\n".encode("utf-8"))
    (tmp_path / "cut.gz").write_bytes(gzip.compress(text)[:400])
    (tmp_path / "meta-less.jsonl").write_bytes(text.split(b"\n", 1)[1])
    cases = {"x.png": "not a JSON line", "notes.txt": "not a JSON line",
             "cut.gz": "unreadable after line", "meta-less.jsonl": "must be the meta event"}
    for name, why in cases.items():
        with pytest.raises(TraceError, match=why):
            plot_trace(read_trace(str(tmp_path / name)), str(tmp_path / "y.svg"))
    assert not (tmp_path / "y.svg").exists()


def test_plot_bad_window(idle_run, tmp_path):
    out = tmp_path / "x.svg"
    with pytest.raises(PlotError, match="before --end"):
        plot_trace(idle_run, str(out), start_s=3.0, end_s=2.0)
    with pytest.raises(PlotError, match=">= 0"):
        plot_trace(idle_run, str(out), start_s=-1.0)
    with pytest.raises(PlotError, match=r"--start 50 s is after the trace's end \(it covers "
                                        r"0-4 s\)"):      # (said: no frame between 50 and 60)
        plot_trace(idle_run, str(out), start_s=50.0, end_s=60.0)
    with pytest.raises(PlotError, match="no frame on air between 0.5 s and 1 s"):
        plot_trace(idle_run, str(out), start_s=0.5, end_s=1.0)   # before the ring formed
    assert list(tmp_path.iterdir()) == []


def _with(evs, *extra):
    """``evs`` with synthetic events inserted in tick order (after those at the same tick)."""
    out = list(evs)
    for e in extra:
        i = next((k for k in range(1, len(out)) if out[k]["t"] > e["t"]), len(out))
        out.insert(i, e)
    return out


def test_interference_and_air_faults(idle_run, tmp_path):
    """Events of faults with no robot (air faults) and bytes on air from no robot."""
    f = frames(idle_run)[30]
    s, e = f["end"] + 1_000, f["end"] + 20_000          # inside the Ttrans gap
    evs = _with(idle_run,
                {"t": s, "ev": "fault", "robot": None, "kind": "burst", "phase": "start",
                 "spec": "burst@x:0.001"},
                {"t": e, "ev": "interference", "start": s, "end": e, "bytes": 1,
                 "collided": False})
    out = tmp_path / "i.vcd"
    summary = write_vcd(evs, str(out))
    assert summary["interference"] == 1
    _, ch, _ = parse_vcd(out)
    assert value_at(ch, "rprs.interference", s * UNITS) == "1"
    assert value_at(ch, "rprs.interference", e * UNITS) == "0"
    assert value_at(ch, "rprs.collision", s * UNITS) == "0"
    assert value_at(ch, "rprs.owner", s * UNITS) == f["src"]        # no robot owns noise
    nxt = f["src"] % 3 + 1                  # switching to transmit (TXEN high): not receiving
    other = ({1, 2, 3} - {f["src"], nxt}).pop()
    assert value_at(ch, f"rprs.R{nxt}.txen", s * UNITS) == "1"
    assert value_at(ch, f"rprs.R{nxt}.rx", s * UNITS) == "0"
    assert value_at(ch, f"rprs.R{other}.rx", s * UNITS) == "x"
    p = plot_trace(evs, str(tmp_path / "i.svg"))
    assert p["interference"] == 1
    assert "burst@x:0.001" in (tmp_path / "i.svg").read_text()


def test_the_waveform_and_the_plot_count_misses_as_the_summary_does(tmp_path):
    """R1's radio fails for 7 s in a ring of four: R1, deaf, reports each of the three healthy
    robots missing. The summary counts R1's three misses only (reports by a robot whose
    radio failed are none); the VCD fired a miss on each healthy robot too, and the plot
    said "6 missed"."""
    evs: list[dict] = []
    w = World(SimConfig(robots=(0, 1, 2, 3), duration=15.0,
                        faults=(Fault("fail", 1, 5.0), Fault("recover", 1, 12.0))),
              on_event=evs.append)
    w.run()
    assert any(e["ev"] == "miss" and e["robot"] != 1 for e in evs)     # R1's, while deaf
    summary = w.summary()
    missed = sum(r["missed"] for r in summary["robots"].values())
    assert missed == 3
    s = write_vcd(evs, str(tmp_path / "run.vcd"))
    _, ch, _ = parse_vcd(tmp_path / "run.vcd")
    assert s["misses"] == missed
    assert not any(ch.get(f"rprs.R{r}.miss") for r in (0, 2, 3))
    assert plot_trace(evs, str(tmp_path / "run.png"))["misses"] == missed


def test_on_the_cpu_model_the_zoom_finds_a_whole_cycle(tmp_path):
    """docs/visualisation.md's own example runs on the CPU model (the command line's default),
    where a hand-over's gap is Ttrans and a handler's time (81,115 ticks): no cycle had every
    gap exactly Ttrans, and the zoom fell back to the window's first frames, from R4."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    evs = _sim(robots=(1, 2, 3, 4), duration=16.0, load=1.0, can=True, cpu=DEFAULT_COSTS,
               faults=(Fault("fail", 1, 8.0), Fault("recover", 1, 15.0)))
    for start in (14.85, 14.9):
        s = plot_trace(evs, str(tmp_path / "z.svg"), start_s=start, end_s=15.6)
        assert s["zoom_robots"][0] == 2 and s["zoom_robots"] == s["zoom_robots"][:1] + [3, 4, 2]
        assert start <= s["zoom_s"][0] < s["zoom_s"][1] <= 15.6
