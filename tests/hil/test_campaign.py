"""Campaigns (hil/campaign, ``rprs campaign``): a grid of seeded runs on Dask distributed, the
results in SQLite, resumable, with statistics. The engine runs on a LocalCluster of two
worker processes and on a real ``dask scheduler`` with two ``dask worker`` processes on
loopback, which must give the same rows."""
from __future__ import annotations

import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil.campaign import engine
from hil.campaign.engine import run_campaign
from hil.campaign.report import ber_series, plot, summarize, wilson
from hil.campaign.runs import check_args
from hil.campaign.seeds import run_key, run_seed
from hil.campaign.spec import SpecError, load_spec
from hil.campaign.store import Store, StoreError
from processes import stop, wait_for
from paths import ROOT

REAL_SOURCE_STATE = engine.source_state

SPEC = """
[campaign]
name = "t"
seeds = 2
root_seed = 11
duration = 3

[grid]
robots = ["1,2", "0,1,2"]
load = ["1"]
checksum = [true]
"""


@pytest.fixture
def spec_file(tmp_path):
    p = tmp_path / "t.toml"
    p.write_text(SPEC)
    return p


@pytest.fixture(autouse=True)
def clean_source(monkeypatch):
    """The tests run from a working tree that may have changes: pretend it is clean, one
    commit (the dirty/commit checks have their own test)."""
    monkeypatch.setattr(engine, "source_state", lambda root=None: ("c0ffee", False))


def _nice():
    # The Dask processes these tests start run at a lower priority, so that the real-time
    # tests beside them (other xdist worker) keep their timing on a 2-core machine.
    os.nice(10)


def rprs(*args, **kw):
    return subprocess.run([sys.executable, "-m", "hil.cli", *args], capture_output=True,
                          text=True, timeout=kw.pop("timeout", 300), preexec_fn=_nice, **kw)


# ---------------------------------------------------------------- statistics and seeds
def test_wilson_interval_matches_published_values():
    # Newcombe (1998), Stat. Med. 17:857, method 3 (score interval without correction)
    for (k, n), (lo, hi) in {(0, 10): (0.0, 0.2775), (1, 10): (0.0179, 0.4042),
                             (5, 10): (0.2366, 0.7634), (10, 10): (0.7225, 1.0)}.items():
        assert wilson(k, n) == pytest.approx((lo, hi), abs=5e-5)


def test_the_ber_plots_ticks_do_not_run_into_each_other(tmp_path, monkeypatch):
    """A grid of ``ber = [0.0, 0.00025, ..., 0.002]`` drew its x ticks as 0.000000,
    0.000250, ... side by side, one unreadable string. Each tick label's box is apart from
    the next one's now."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    points = [{"point": {"robots": "1,2", "ber": b / 4000}, "failed_rate": b / 400,
               "failed_ci95": (0.0, 0.1)} for b in range(9)]
    boxes: list = []
    savefig = plt.Figure.savefig

    def keep(fig, *a, **k):
        savefig(fig, *a, **k)              # drawn: the tick labels have their places
        ax = fig.axes[0]
        renderer = fig.canvas.get_renderer()
        boxes.extend(t.get_window_extent(renderer) for t in ax.get_xticklabels()
                     if t.get_text() and t.get_visible())
    monkeypatch.setattr(plt.Figure, "savefig", keep)
    assert plot(points, [], tmp_path) == [str(tmp_path / "failure_vs_ber.png")]
    boxes.sort(key=lambda b: b.x0)
    assert len(boxes) >= 3
    assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:])), [(b.x0, b.x1) for b in boxes]


def test_the_ber_plot_draws_one_line_per_rest_of_point_labelled_with_what_varies(tmp_path,
                                                                                monkeypatch):
    # robots and load both vary besides ber: four lines, none merging two loads of one ring
    points = [{"point": {"robots": r, "load": ld, "checksum": True, "ber": b},
               "failed_rate": 0.1 * b, "failed_ci95": (0.0, 0.2)}
              for r in ("1,2", "0,1,2") for ld in ("1", "saturate") for b in (0.02, 0.01)]
    series = ber_series(points)
    assert sorted(series) == ["checksum=true load=1 robots=0,1,2",
                              "checksum=true load=1 robots=1,2",
                              "checksum=true load=saturate robots=0,1,2",
                              "checksum=true load=saturate robots=1,2"]
    assert all([p[0] for p in pts] == [0.01, 0.02] for pts in series.values())
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    seen, legend = [], plt.Axes.legend
    titles, set_title = [], plt.Axes.set_title
    monkeypatch.setattr(plt.Axes, "legend", lambda ax, *a, **k: (
        seen.append(ax.get_legend_handles_labels()[1]), legend(ax, *a, **k))[1])
    monkeypatch.setattr(plt.Axes, "set_title", lambda ax, t, *a, **k: (
        titles.append(t), set_title(ax, t, *a, **k))[1])
    assert plot(points, [], tmp_path) == [str(tmp_path / "failure_vs_ber.png")]
    # the labels drawn, in order: what varies; checksum, the same at every point, is named
    # once, in the title
    assert seen == [list(ber_series(points, {"checksum": True}))]
    assert seen[0] == ["load=1 robots=0,1,2", "load=1 robots=1,2", "load=saturate robots=0,1,2",
                       "load=saturate robots=1,2"]
    assert titles == ["every point: checksum=true"]


def test_seeds_depend_on_the_point_and_index_only():
    a = run_seed(11, '{"robots":"1,2"}', 0)
    assert a == run_seed(11, '{"robots":"1,2"}', 0)           # repeatable alone
    assert len({run_seed(11, '{"robots":"1,2"}', i) for i in range(100)}) == 100
    assert a != run_seed(12, '{"robots":"1,2"}', 0) != run_seed(11, '{"robots":"1,3"}', 0)
    assert run_key('{"robots":"1,2"}', 3).endswith("/3")


def test_a_spec_expands_its_grid_and_checks_every_point(spec_file, tmp_path):
    s = load_spec(spec_file, check=check_args)
    assert s.runs == 4 and len(s.points) == 2
    assert s.points[0].args == ("--checksum", "--duration", "3", "--load", "1",
                                "--robots", "1,2")          # in the grid's order
    for text, words in (("[grid]\nrobots = ['9']\n", "robot"),
                        ("[grid]\nseed = [1]\n", "the campaign sets it"),
                        ("[grid]\nfault = ['fail:1@2']\n", "each value is a list"),
                        ("[campaign]\nseeds = 0\n", "seeds must be an integer >= 1"),
                        ("[camp]\n", "unknown table"),
                        # a value twice: planned twice, run twice, one result kept
                        ("[grid]\nrobots = ['0,1,2', '0,1,2']\n", "twice"),
                        # empty (or comments only): the wrong file, not 10 default runs
                        ("", "no \\[campaign\\] or \\[grid\\] table"),
                        ("# nothing yet\n", "nothing says what to run"),
                        ("not toml [", "not TOML")):
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        with pytest.raises(SpecError, match=words):
            load_spec(bad, check=check_args)


# ---------------------------------------------------------------- the engine
def run_cli(spec_file, db, *extra):
    """``rprs campaign run`` into ``db`` (local cluster of 2 unless ``extra`` says otherwise);
    the completed process, checked for success."""
    r = rprs("campaign", "run", str(spec_file), "--db", str(db), *(extra or ("--workers", "2")),
             "--allow-dirty", "--no-progress")
    assert r.returncode == 0, r.stderr
    return r


def _rows(db):
    with sqlite3.connect(db) as c:
        return {k: (s, json.loads(m) if m else None) for k, s, m in
                c.execute("SELECT run_key, seed, metrics FROM runs")}


def test_a_campaign_on_a_local_cluster_of_two_workers(spec_file, tmp_path):
    db = tmp_path / "a.sqlite"
    r = run_cli(spec_file, db)
    assert "4 runs planned, 0 already in" in r.stdout and "(0 crashed)" in r.stdout
    assert "on 2 worker(s)" in r.stdout
    if engine.dashboard_available():
        assert "Dask dashboard http://127.0.0.1:" in r.stderr, r.stderr
    store = Store(db)
    rows = store.rows()
    assert len(rows) == 4 and {r["status"] for r in rows} == {"ok"}
    assert len({r["worker"] for r in rows}) >= 1 and all(r["metrics"]["submitted"] > 0
                                                        for r in rows)
    # run-missing: nothing is run twice
    assert "4 already in" in run_cli(spec_file, db).stdout
    assert _rows(db) == {r["run_key"]: (r["seed"], r["metrics"]) for r in rows}
    # any run repeats alone with its rprs sim command
    r = rows[0]
    p = rprs("sim", *r["args"], "--seed", str(r["seed"]), "--json", "--no-progress")
    s = json.loads(p.stdout)
    assert (s["submitted"], s["delivered"], s["failed"]) == \
        (r["metrics"]["submitted"], r["metrics"]["delivered"], r["metrics"]["failed"])


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# a real `dask scheduler` and two `dask worker` processes, about 25 s: the slow tier (the fast
# tier keeps the local cluster's test)
@pytest.mark.slow
def test_a_real_scheduler_and_two_workers_give_the_same_rows(spec_file, tmp_path):
    run_cli(spec_file, tmp_path / "local.sqlite")
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "dask"]
    procs = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, preexec_fn=_nice)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen([*dask, "worker", addr, "--nthreads", "1",
                                           "--no-dashboard"], stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL, preexec_fn=_nice))
        remote = run_cli(spec_file, tmp_path / "remote.sqlite", "--scheduler", addr,
                         "--workers", "2")
    finally:
        stop(procs)
    assert "4 run now (0 crashed)" in remote.stdout and "on 2 worker(s)" in remote.stdout
    assert _rows(tmp_path / "remote.sqlite") == _rows(tmp_path / "local.sqlite")


@pytest.mark.slow  # a real scheduler, its worker killed and another started: about 40 s
def test_campaign_run_says_when_no_worker_is_left_and_when_one_is_back(tmp_path):
    """A campaign on a real scheduler whose only worker is killed mid-way (SIGKILL to the
    worker and its nanny): ``campaign run`` says on stderr that no worker is connected, says
    so again when a new worker joins, and ends with every run stored, none lost."""
    import threading
    spec = tmp_path / "w.toml"
    spec.write_text(SPEC.replace("seeds = 2", "seeds = 12\nchunk = 1")
                    .replace("duration = 3", "duration = 120"))
    db = tmp_path / "w.sqlite"
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "dask"]

    def worker():
        return subprocess.Popen([*dask, "worker", addr, "--nthreads", "1", "--no-dashboard"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True, preexec_fn=_nice)
    procs = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, preexec_fn=_nice)]
    lines: list[str] = []
    workers = [worker()]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "hil.cli", "campaign", "run", str(spec),
                          "--db", str(db), "--scheduler", addr, "--workers", "1",
                          "--allow-dirty", "--no-progress"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=env, preexec_fn=_nice)

    def read():
        with p.stderr:
            lines.extend(p.stderr)
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        def stored() -> int:
            try:
                with sqlite3.connect(db) as c:
                    return c.execute("SELECT count(*) FROM runs").fetchone()[0]
            except sqlite3.Error:
                return 0
        assert wait_for(lambda: db.exists() and stored() >= 2, 120.0), "".join(lines)
        os.killpg(workers[0].pid, signal.SIGKILL)
        assert wait_for(lambda: any("no worker is connected" in ln for ln in lines), 40.0), \
            "".join(lines)
        workers.append(worker())
        assert wait_for(lambda: any("worker(s) connected again" in ln for ln in lines), 60.0), \
            "".join(lines)
        p.wait(timeout=300)
        with p.stdout:
            out = p.stdout.read()
    finally:
        for w in workers:
            if w.poll() is None:
                os.killpg(w.pid, signal.SIGKILL)
            w.wait(timeout=30)
        if p.poll() is None:
            p.kill()
            p.wait(timeout=30)
        stop(procs)
    reader.join(10)
    assert p.returncode == 0, "".join(lines)
    assert "24 runs planned" in out and "lost" not in out
    assert len(_rows(db)) == 24


@pytest.mark.slow  # a real scheduler and a worker from an edited copy: about 15 s
def test_a_worker_running_other_code_is_refused_before_any_run(spec_file, tmp_path):
    """A worker started from an edited copy of the packages (one comment added) runs other
    code than the client: the campaign refuses it before it sends a run, naming it, and
    stores nothing; rows record the digest of the code that made them."""
    import shutil

    from hil.campaign.code import PACKAGES, code_identity
    copy = tmp_path / "copy"
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, copy / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    with open(copy / "hil" / "campaign" / "runs.py", "a") as fh:
        fh.write("# an edit the client does not have\n")
    assert code_identity(str(copy)) != code_identity()
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "dask"]
    env = dict(os.environ, PYTHONPATH=str(copy))
    procs = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, preexec_fn=_nice)]
    try:
        procs.append(subprocess.Popen([*dask, "worker", addr, "--nthreads", "1",
                                       "--no-dashboard"], cwd=copy, env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                      preexec_fn=_nice))
        r = rprs("campaign", "run", str(spec_file), "--db", str(tmp_path / "m.sqlite"),
                 "--scheduler", addr, "--workers", "1", "--allow-dirty", "--no-progress")
    finally:
        stop(procs)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert "1 of 1 worker(s) run other code than this client" in r.stderr, r.stderr
    assert code_identity(str(copy)) in r.stderr and "start them from this checkout" in r.stderr
    assert Store(tmp_path / "m.sqlite").rows() == []


def test_every_row_records_the_code_that_made_it(spec_file, tmp_path):
    from hil.campaign.code import code_identity
    spec = load_spec(spec_file, check=check_args)
    store = Store(tmp_path / "c.sqlite")
    _run_in_process(spec, store)
    assert {r["code"] for r in store.rows()} == {code_identity()}
    assert len(code_identity()) == 16


@pytest.mark.slow  # 24 runs killed mid-way and resumed: about 23 s
def test_a_killed_campaign_resumes_losing_nothing_and_repeating_nothing(tmp_path):
    spec = tmp_path / "k.toml"
    # 24 runs of about half a second, one a task, so that the kill lands in the middle
    spec.write_text(SPEC.replace("seeds = 2", "seeds = 12\nchunk = 1")
                    .replace("duration = 3", "duration = 40"))
    db = tmp_path / "k.sqlite"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "hil.cli", "campaign", "run", str(spec), "--db", str(db),
           "--workers", "2", "--allow-dirty", "--no-progress"]
    # its output to a file, not pipes: nobody reads them while it runs, and pipes left open
    # warned (ResourceWarning: unclosed file <_io.BufferedReader>) when the Popen was collected
    log = tmp_path / "killed.log"
    with open(log, "wb") as out:
        p = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env,
                             start_new_session=True, preexec_fn=_nice)
    try:
        deadline = time.monotonic() + 240
        n = 0
        while time.monotonic() < deadline and p.poll() is None:
            if db.exists():
                try:
                    with sqlite3.connect(db) as c:
                        n = c.execute("SELECT count(*) FROM runs").fetchone()[0]
                except sqlite3.Error:
                    n = 0
                if n >= 4:
                    break
            time.sleep(0.2)
        assert p.poll() is None and 4 <= n < 24, (n, p.poll(), log.read_text()[-2000:])
        os.killpg(p.pid, signal.SIGKILL)            # the campaign and its workers
        p.wait(timeout=30)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=30)
    before = _rows(db)
    assert 4 <= len(before) < 24
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300,
                       preexec_fn=_nice)
    assert r.returncode == 0, r.stderr
    assert f"{len(before)} already in" in r.stdout
    after = _rows(db)
    assert len(after) == 24
    assert {k: after[k] for k in before} == before       # nothing re-run or changed


def _crash_on_odd_seeds(cfg):
    from hil.campaign.runs import metrics_of
    if cfg.seed % 2:
        raise RuntimeError(f"deliberately broken run, seed {cfg.seed}")
    return metrics_of(cfg)


def _run_in_process(spec, store, **kw):
    """``run_campaign`` on a cluster of one in-process worker with two threads (no worker
    processes: quick, and functions need not be importable by a worker)."""
    from dask.distributed import Client
    cluster = engine.local_cluster(1, processes=False, threads_per_worker=2)
    client = Client(cluster)
    try:
        return run_campaign(spec, store, client=client, **kw)
    finally:
        client.close()
        cluster.close()


def test_the_dashboard_link_is_given_and_serves_the_dashboard(spec_file, tmp_path):
    """With bokeh installed (the ``campaign`` extra) the embedded cluster serves Dask's
    dashboard on a free loopback port, and the campaign gives its link while it runs."""
    import urllib.request
    pytest.importorskip("bokeh", reason="bokeh (the campaign extra) serves the dashboard")
    spec = load_spec(spec_file, check=check_args)
    seen = []

    def fetch(link: str) -> None:
        with urllib.request.urlopen(link, timeout=20) as r:
            seen.append((link, r.status, b"bokeh" in r.read().lower()))
    _run_in_process(spec, Store(tmp_path / "d.sqlite"), on_dashboard=fetch)
    assert len(seen) == 1
    link, status, bokeh_page = seen[0]
    assert link.startswith("http://127.0.0.1:") and link.endswith("/status")
    assert status == 200 and bokeh_page


def test_the_worker_watch_says_when_no_worker_is_left_and_when_workers_are_back():
    """With every worker gone a campaign waits and its progress stops: ``WorkerWatch`` tells
    the change (0 workers, then some again), once each, never while workers come and go."""
    seen_workers = iter([2, 1, 0, 0, 0, 1, 3, 0, 2])

    class Client:
        def scheduler_info(self):
            return {"workers": {f"w{i}": {} for i in range(next(seen_workers))}}

    told: list[int] = []
    w = engine.WorkerWatch(Client(), told.append)
    for _ in range(9):
        w.check()
    assert told == [0, 1, 0, 2]


def test_a_campaigns_own_metrics_from_each_runs_trace_are_stored_and_reported(tmp_path,
                                                                            capsys):
    """``[campaign] metrics = "module:function"``: each run's trace events and world go to
    the function; what it returns is stored with the run (``custom``), equal to the same
    count made by hand from the run alone, and the report gives each metric's mean with its
    interval per point."""
    from hil.campaign.runs import sim_config_for
    from hil.cli import main
    from hil.sim import events as E
    from hil.sim.world import World
    f = tmp_path / "m.toml"
    f.write_text(SPEC.replace('duration = 3\n', 'duration = 3\nmetrics = '
                              '"campaign_metrics:frames"\n'))
    spec = load_spec(f, check=check_args)
    assert spec.metrics == "campaign_metrics:frames"
    store = Store(tmp_path / "m.sqlite")
    _run_in_process(spec, store)
    rows = store.rows()
    assert rows and all(r["status"] == "ok" for r in rows)
    for r in rows[:2]:
        evs: list = []
        w = World(sim_config_for(r["args"], r["seed"]), listeners=[evs.append])
        w.run()
        n = sum(type(e) is E.FrameOnAir for e in evs)
        assert r["metrics"]["custom"]["frames on air"] == n > 0
        assert r["metrics"]["custom"]["occupations"] == w.air.occupations
    store.close()
    assert main(["campaign", "report", str(tmp_path / "m.sqlite")]) == 0
    out = capsys.readouterr().out
    assert out.count("  frames on air: ") == 2 and "mean of 2 runs" in out


@pytest.mark.parametrize("hook,says", [
    ("nosuch_module:f", "cannot import nosuch_module"),
    ("campaign_metrics:nope", "no function nope"),
    ("campaign_metrics", "give 'module:function'"),
    (".relative:f", "an absolute module name"),
    ("hook_syntax:f", "importing hook_syntax failed: SyntaxError: expected ':'"),
    ("hook_raises:f", "importing hook_raises failed: RuntimeError: not today")])
def test_a_metrics_hook_that_cannot_be_used_is_refused_with_the_file(tmp_path, hook, says):
    """A hook module that fails to import other than by ImportError (a syntax error in the
    user's own module, one that raises, a relative name) was a traceback."""
    (tmp_path / "hook_syntax.py").write_text("def f(events, world)\n    return {}\n")
    (tmp_path / "hook_raises.py").write_text("raise RuntimeError('not today')\n")
    f = tmp_path / "bad.toml"
    f.write_text(SPEC.replace('duration = 3\n', f'duration = 3\nmetrics = "{hook}"\n'))
    with pytest.raises(SpecError, match=says):
        load_spec(f, check=check_args)


def test_a_metrics_hook_beside_its_campaign_file_is_found_from_anywhere(tmp_path):
    """docs/campaigns.md's example, a ``mymetrics.py`` beside the campaign file, was "cannot
    import mymetrics" unless its directory was on PYTHONPATH (the ``rprs`` script does not
    look in the working directory). The campaign file's directory is searched, by the
    command and by the embedded cluster's worker processes (a run in another directory)."""
    d = tmp_path / "study"
    d.mkdir()
    (d / "mymetrics_beside.py").write_text(
        "def frames(events, world):\n    return {'occupations': world.air.occupations}\n")
    (d / "s.toml").write_text(
        '[campaign]\nseeds = 1\nduration = 2\nmetrics = "mymetrics_beside:frames"\n'
        '[grid]\nrobots = ["1,2"]\n')
    r = subprocess.run([sys.executable, "-m", "hil.cli", "campaign", "run", str(d / "s.toml"),
                        "--workers", "1", "--no-progress", "--allow-dirty"], cwd="/",
                       capture_output=True, text=True, timeout=300,
                       env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"})
    assert r.returncode == 0, r.stderr
    store = Store(d / "s.sqlite", read_only=True)
    rows = store.rows()
    store.close()
    assert [row["status"] for row in rows] == ["ok"]
    assert rows[0]["metrics"]["custom"]["occupations"] > 0


def test_a_metric_that_is_no_number_crashes_its_run_with_the_reason(tmp_path):
    f = tmp_path / "nan.toml"
    f.write_text(SPEC.replace('duration = 3\n', 'duration = 3\nmetrics = '
                              '"campaign_metrics:not_a_number"\n'))
    store = Store(tmp_path / "n.sqlite")
    _run_in_process(load_spec(f, check=check_args), store)
    rows = store.rows()
    assert rows and all(r["status"] == "crashed" and "must return {name: number}" in r["error"]
                        for r in rows)


def test_a_broken_run_is_recorded_and_reported_not_lost(spec_file, tmp_path):
    spec = load_spec(spec_file, check=check_args)
    store = Store(tmp_path / "c.sqlite")
    out = _run_in_process(spec, store, measure=_crash_on_odd_seeds)
    rows = store.rows()
    odd = [r for r in rows if r["seed"] % 2]
    unexpected = [r["error"] for r in rows if r["status"] != "ok" and not r["seed"] % 2]
    assert not unexpected, "\n\n".join(unexpected)      # a run that should not have crashed
    assert out.ran == 4 and out.crashed == len(odd) > 0
    assert all(r["status"] == "crashed" and "deliberately broken run" in r["error"] and
               "Traceback" in r["error"] for r in odd)
    points = summarize(rows)
    assert sum(p["crashed"] for p in points) == len(odd)
    cmds = [f["command"] for p in points for f in p["failing"] if f["broke"] == ["crashed"]]
    assert sorted(cmds) == sorted(f"rprs sim {' '.join(r['args'])} --seed {r['seed']}"
                                  for r in odd)
    # what it raised, its traceback's last line: a crash in the campaign's metrics hook is
    # not in what that command repeats
    raised = [f["error"] for p in points for f in p["failing"]]
    assert len(raised) == len(odd) and all(
        e.startswith("RuntimeError: deliberately broken run, seed ") for e in raised), raised


def test_the_local_cluster_takes_no_fixed_port(recwarn):
    """With port 8787 taken (another campaign's cluster, a dashboard), the embedded cluster
    warned "Port 8787 is already in use" and left the socket of its failed bind open (a
    ResourceWarning that failed the broken-run test under -W error). Its HTTP server now
    listens on a free loopback port."""
    from dask.distributed import Client
    held = socket.socket()
    try:
        held.bind(("0.0.0.0", 8787))
        held.listen()
    except OSError:
        pass                                   # taken already: the same test
    try:
        with engine.local_cluster(1, processes=False) as cluster, Client(cluster) as client:
            assert client.submit(sum, [1, 2]).result(timeout=30) == 3
            port = cluster.scheduler.http_server.port
    finally:
        held.close()
    assert port != 8787
    assert not [w for w in recwarn if "8787" in str(w.message)], [str(w.message) for w in recwarn]


def test_results_of_another_commit_or_a_dirty_tree_are_not_mixed(spec_file, tmp_path,
                                                                  monkeypatch):
    spec = load_spec(spec_file, check=check_args)
    store = Store(tmp_path / "m.sqlite")
    store.add([{"run_key": "x/0", "point_key": "{}", "args": [], "seed_index": 0, "seed": 1,
                "status": "ok", "error": None, "metrics": None, "wall_s": 0.0,
                "worker": "w"}], "deadbeef", False)
    with pytest.raises(StoreError, match="deadbeef"):
        run_campaign(spec, store, workers=1)
    monkeypatch.setattr(engine, "source_state", lambda root=None: ("deadbeef", True))
    with pytest.raises(StoreError, match="uncommitted"):
        run_campaign(spec, store, workers=1)
    other = Store(tmp_path / "o.sqlite")
    other.claim("another", 1)
    with pytest.raises(StoreError, match="holds campaign 'another'"):
        run_campaign(spec, other, workers=1, allow_dirty=True)


def test_a_refused_run_leaves_no_empty_results_file(spec_file, tmp_path, monkeypatch, capsys):
    """``campaign run`` refused for a dirty tree left an empty results file behind, which
    ``campaign report`` then read as a campaign "?" of 0 runs. A file it made for nothing is
    removed; a file that was there is left as it was."""
    from hil.cli import main
    monkeypatch.setattr(engine, "source_state", lambda root=None: ("deadbeef", True))
    db = tmp_path / "new.sqlite"
    assert main(["campaign", "run", str(spec_file), "--db", str(db), "--workers", "1"]) == 2
    assert "uncommitted" in capsys.readouterr().err and not db.exists()
    kept = tmp_path / "kept.sqlite"
    Store(kept).close()
    assert main(["campaign", "run", str(spec_file), "--db", str(kept), "--workers", "1"]) == 2
    assert kept.exists()
    # Ctrl-C before any run was stored (while the cluster started) left a file of 0 runs
    # marked as this campaign's; README: an interrupted run leaves no output file of it
    monkeypatch.setattr(engine, "source_state", lambda root=None: ("c0ffee", False))

    def interrupted(spec, store, **kw):
        store.claim(spec.name, spec.root_seed)
        raise KeyboardInterrupt
    monkeypatch.setattr(engine, "run_campaign", interrupted)
    assert main(["campaign", "run", str(spec_file), "--db", str(db), "--workers", "1"]) == 130
    assert not db.exists()


def test_the_real_source_state_is_a_commit_of_this_checkout():
    commit, dirty = REAL_SOURCE_STATE()
    head = subprocess.run(["git", "-C", str(engine.SOURCE), "rev-parse", "HEAD"],
                          capture_output=True, text=True)
    if head.returncode != 0:
        pytest.skip("not a git checkout (an installed package): no commit to compare")
    assert commit == head.stdout.strip() and isinstance(dirty, bool)


# ---------------------------------------------------------------- the command line
def test_cli_run_report_and_export(spec_file, tmp_path):
    db = tmp_path / "cli.sqlite"
    st = rprs("campaign", "status", str(spec_file), "--db", str(db))
    assert st.returncode == 0 and "4 runs, none done yet" in st.stdout, st.stderr
    r = run_cli(spec_file, db)
    assert "4 runs planned, 0 already in" in r.stdout and "0 crashed" in r.stdout
    st = rprs("campaign", "status", str(spec_file), "--db", str(db))
    assert st.returncode == 0, st.stderr
    assert "4 runs; done 4, crashed 0" in st.stdout and "lost 0" in st.stdout and \
        "missing 0" in st.stdout
    rep = rprs("campaign", "report", str(db), "--json", "--plots", str(tmp_path / "plots"))
    assert rep.returncode == 0, rep.stderr
    data = json.loads(rep.stdout)
    assert len(data["points"]) == 2 and all(p["runs"] == 2 for p in data["points"])
    assert all(Path(f).is_file() for f in data["plots"])
    ex = rprs("campaign", "export", str(db), "--csv", str(tmp_path / "runs.csv"),
              "--parquet", str(tmp_path / "runs.parquet"))
    assert ex.returncode == 0, ex.stderr
    import csv
    with open(tmp_path / "runs.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == 4 and {r["status"] for r in table} == {"ok"}
    assert {r["param_robots"] for r in table} == {"1,2", "0,1,2"}
    pq = pytest.importorskip("pyarrow.parquet", reason="pyarrow not installed (the "
                             "'campaign' extra has it)")
    t = pq.read_table(tmp_path / "runs.parquet").to_pylist()
    assert sorted((r["run_key"], r["m_submitted"]) for r in t) == \
        sorted((r["run_key"], int(r["m_submitted"])) for r in table)


@pytest.mark.parametrize("args,words", [
    (("campaign", "run", "/no/such.toml"), "cannot read campaign file"),
    (("campaign", "report", "/no/such.sqlite"), "no results file"),
    (("campaign", "export", "/no/such.sqlite", "--csv", "x.csv"), "no results file"),
    (("campaign", "run", "{spec}", "--workers", "0"), "--workers must be at least 1"),
    (("campaign", "status", "{spec}", "--db", "{dir}"), "is a directory"),
    (("campaign", "run", "{huge}"), "more than 1,000,000: split it"),
])
def test_cli_mistakes_are_one_line(args, words, spec_file, tmp_path):
    """(``status --db DIR`` said "none done yet (no DIR)"; a campaign of 10^11 runs was
    planned whole, minutes and GBs in silence, before the first ran.)"""
    huge = tmp_path / "huge.toml"
    huge.write_text('[campaign]\nseeds = 100000000000\n[grid]\nrobots = ["1,2"]\n')
    r = rprs(*[a.format(spec=spec_file, dir=tmp_path, huge=huge) for a in args])
    assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_the_progress_bar_shows_runs_per_second_and_time_left_on_a_terminal(spec_file,
                                                                           tmp_path):
    """On a terminal (stderr is a pty here) ``campaign run`` draws a bar with M/N runs, runs/s
    and the time left; with ``--no-progress`` or a pipe it draws nothing (the other tests)."""
    import pty
    import re
    master, slave = pty.openpty()
    p = subprocess.Popen([sys.executable, "-m", "hil.cli", "campaign", "run", str(spec_file),
                          "--db", str(tmp_path / "bar.sqlite"), "--workers", "1",
                          "--allow-dirty"], stdout=subprocess.PIPE, stderr=slave,
                         preexec_fn=_nice, env=dict(os.environ, COLUMNS="120", TERM="xterm"))
    os.close(slave)
    seen = bytearray()
    stdout = b""
    try:
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:                      # EIO: the child closed its end
                break
            if not chunk:
                break
            seen += chunk
        assert p.wait(timeout=300) == 0
        stdout = p.stdout.read()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=30)
        p.stdout.close()                         # else: ResourceWarning, unclosed file
        os.close(master)
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", seen.decode(errors="replace"))
    assert "campaign t" in text
    assert re.search(r"\b[1-4]/4\b", text), text[-500:]             # M of N runs
    assert re.search(r"\d+\.\d runs/s", text), text[-500:]
    # the time left: the runs left at the rate shown (a run of 4 runs: under a minute)
    assert re.search(r"runs/s, (0:00:\d\d|-:--:--) left", text), text[-500:]
    assert b"4 runs planned" in stdout


@pytest.mark.parametrize("fmt", ["--csv", "--parquet"])
def test_an_export_that_cannot_be_written_names_its_file_and_leaves_it(tmp_path, capsys, fmt,
                                                                      full_device):
    """A full disk under ``campaign export`` said "cannot write None: No space left on
    device" (the CSV writer's OSError carries no file name), and pyarrow removes the file it
    failed to write: as root, ``--parquet /dev/full`` deleted /dev/full."""
    from hil.cli import main
    if fmt == "--parquet":
        pytest.importorskip("pyarrow", reason="pyarrow not installed (the 'campaign' extra has it)")
    full = full_device
    db = tmp_path / "r.sqlite"
    Store(db).close()
    code = main(["campaign", "export", str(db), fmt, str(full)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"rprs: error: cannot write {full}: No space left on device"), err
    assert full.is_char_device()


def test_an_export_onto_its_own_results_or_twice_onto_one_file_is_refused(tmp_path, capsys):
    """``campaign export R.sqlite --csv R.sqlite`` wrote the CSV over the results file, and
    ``--csv F --parquet F`` left only the Parquet file, both with exit status 0: refused in
    one line, the results file untouched."""
    from hil.cli import main
    db = tmp_path / "r.sqlite"
    Store(db).close()
    before = db.read_bytes()
    for args, says in (
            (["--csv", str(db)], f"--csv names the results file {db} itself"),
            (["--parquet", str(tmp_path / "." / "r.sqlite")], "--parquet names the results"),
            (["--csv", str(tmp_path / "x"), "--parquet", str(tmp_path / "x")],
             "--csv and --parquet name the same file")):
        code = main(["campaign", "export", str(db), *args])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
        assert says in err, err
    assert db.read_bytes() == before and not (tmp_path / "x").exists()


def test_status_counts_only_its_own_campaigns_runs(spec_file, tmp_path, capsys):
    """``campaign status`` counted every row of the results file: another campaign's file
    (refused by ``run``) or a grid shrunk since gave done + missing above the runs planned.
    It refuses another campaign's file as ``run`` does, and counts the spec's own runs."""
    from hil.cli import main
    from hil.campaign.seeds import run_key
    spec = load_spec(spec_file, check=check_args)
    db = tmp_path / "r.sqlite"
    store = Store(db)
    store.claim(spec.name, spec.root_seed)
    keys = [run_key(p.key, i) for p in spec.points for i in range(spec.seeds)]
    rows = [{"run_key": k, "point_key": "{}", "args": [], "seed_index": 0, "seed": 1,
             "status": "ok", "error": None, "metrics": {}, "wall_s": 0.0, "worker": "w"}
            for k in keys[:1] + ["another-point/0", "another-point/1"]]
    store.add(rows, "abc", False)
    store.close()
    assert main(["campaign", "status", str(spec_file), "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert f"{spec.runs} runs; done 1," in out and f"missing {spec.runs - 1}" in out, out
    other = tmp_path / "other.toml"
    other.write_text(spec_file.read_text().replace("root_seed = 11", "root_seed = 99"))
    assert main(["campaign", "status", str(other), "--db", str(db)]) == 2
    err = capsys.readouterr().err
    assert "holds campaign" in err and "use another --db" in err and err.count("\n") == 1


def test_a_claimed_file_stays_claimed_when_closed_without_runs(tmp_path):
    """``claim`` commits its mark: a file claimed and closed before any run is stored (a
    campaign stopped at once) still refuses another campaign."""
    db = tmp_path / "c.sqlite"
    store = Store(db)
    store.claim("one", 1)
    store.close()
    store = Store(db)
    try:
        assert store.meta() == {"name": "one", "root_seed": "1"}
        with pytest.raises(StoreError, match="holds campaign 'one'"):
            store.holds("two", 1)
    finally:
        store.close()


def test_negative_retries_are_refused(spec_file, tmp_path, capsys):
    from hil.cli import main
    assert main(["campaign", "run", str(spec_file), "--db", str(tmp_path / "r.sqlite"),
                 "--retries", "-1"]) == 2
    assert "--retries must be 0 or more" in capsys.readouterr().err


def _results(store):
    return {r["run_key"]: (r["status"], r["metrics"]) for r in store.rows()}


def _undisturbed(spec, tmp_path):
    store = Store(tmp_path / "clean.sqlite")
    _run_in_process(spec, store)
    return _results(store)


def test_a_task_the_cluster_loses_is_sent_again_or_stored_lost_never_as_a_result(
        spec_file, tmp_path, monkeypatch):
    """A task that fails (its worker died: Dask's KilledWorker) is no result: sent again
    (``retries``), and if lost every time stored ``lost``, left out of the report, shown by
    ``campaign status`` and run again by the next ``campaign run``, which then holds what an
    undisturbed campaign holds."""
    import functools

    from dask.distributed import Client

    from campaign_faults import lose_always, lose_first
    spec = load_spec(spec_file, check=check_args)
    clean = _undisturbed(spec, tmp_path)
    cluster = engine.local_cluster(1, processes=False, threads_per_worker=1)
    client = Client(cluster)
    try:                                 # (functions of a module: pickled by reference)
        monkeypatch.setattr(engine, "run_chunk",
                            functools.partial(lose_first, str(tmp_path / "lost")))
        retried = run_campaign(spec, Store(tmp_path / "r.sqlite"), client=client)
        monkeypatch.setattr(engine, "run_chunk", lose_always)
        store = Store(tmp_path / "l.sqlite")
        gone = run_campaign(spec, store, client=client, retries=1)
        assert store.counts() == {"ok": 0, "crashed": 0, "lost": 4}
        assert summarize(store.rows()) == []                 # no result to report
        monkeypatch.undo()
        monkeypatch.setattr(engine, "source_state", lambda root=None: ("c0ffee", False))
        again = run_campaign(spec, store, client=client)     # the lost runs, run again
    finally:
        client.close()
        cluster.close()
    assert (retried.lost, retried.crashed, retried.ran) == (0, 0, 4) and retried.retried > 0
    assert _results(Store(tmp_path / "r.sqlite")) == clean
    assert (gone.lost, gone.crashed) == (4, 0)
    assert again.skipped == 0 and again.ran == 4 and again.lost == 0
    assert _results(store) == clean and store.counts()["lost"] == 0


KILLED_DRIVER = """
import functools, json, sys

import dask
from dask.distributed import Client

from campaign_faults import die_once
from hil.campaign import engine
from hil.campaign.engine import run_campaign
from hil.campaign.runs import check_args
from hil.campaign.spec import load_spec
from hil.campaign.store import Store


def main(spec_path, db, marker):
    engine.source_state = lambda root=None: ("c0ffee", False)
    spec = load_spec(spec_path, check=check_args)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        cluster = engine.local_cluster(2)
        client = Client(cluster)
        try:
            out = run_campaign(spec, Store(db), client=client,
                               measure=functools.partial(die_once, marker))
        finally:
            client.close()
            cluster.close()
    print(json.dumps({"retried": out.retried, "lost": out.lost, "crashed": out.crashed}))


if __name__ == "__main__":
    main(*sys.argv[1:])
"""


@pytest.mark.slow  # a LocalCluster of worker processes, one killed: about 15 s
def test_a_worker_killed_mid_campaign_changes_no_count_of_the_report(spec_file, tmp_path):
    """A worker process dies mid-run (os._exit, as the OOM killer would) and the scheduler
    gives up on its task at once (allowed-failures 0): the engine sends the task again, and
    the report's counts are the undisturbed campaign's. (In a process of its own: the
    worker processes' multiprocessing resource tracker outlives the cluster.)"""
    spec = load_spec(spec_file, check=check_args)
    clean = _undisturbed(spec, tmp_path)
    driver = tmp_path / "killed.py"
    driver.write_text(KILLED_DRIVER)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]))
    p = subprocess.run([sys.executable, str(driver), str(spec_file), str(tmp_path / "k.sqlite"),
                        str(tmp_path / "died")], capture_output=True, text=True, timeout=300,
                       env=env, preexec_fn=_nice)
    assert p.returncode == 0, p.stderr[-3000:]
    out = json.loads(p.stdout.strip().splitlines()[-1])
    assert (tmp_path / "died").exists()                  # a worker did die
    assert out["retried"] > 0 and out["lost"] == 0 and out["crashed"] == 0
    store = Store(tmp_path / "k.sqlite")
    assert _results(store) == clean
    assert summarize(store.rows()) == summarize(list(Store(tmp_path / "clean.sqlite").rows()))


def _row(point_key, i, **metrics):
    m = {"submitted": 10, "delivered": 10, "failed": 0, "pending": 0, "duplicates": 0,
         "misdelivered": 0, "corrupted_acted_on": 0, "collisions": 0, "membership_changes": 0,
         "reformations": 1, "reform_max_s": 1.0 + i / 100, "not_reformed": 0}
    m.update(metrics)
    return {"run_key": f"{point_key}/{i}", "point_key": point_key, "args": ["--robots", "1,2"],
            "seed_index": i, "seed": i, "status": "ok", "metrics": m, "error": None,
            "wall_s": 0.1, "worker": "w"}


def test_a_duplicate_breaks_an_invariant_only_with_the_checksum():
    """docs/guarantees.md promises nothing delivered twice only with the checksum extension:
    without it a duplicate is counted, not a broken run."""
    from hil.campaign.runs import broken
    m = _row('{"x":1}', 0, duplicates=2)["metrics"]
    assert broken(m, ["--robots", "1,2"]) == []
    assert broken(m, ["--robots", "1,2", "--checksum"]) == ["delivered twice"]
    assert broken({**m, "duplicates": 0, "misdelivered": 1}, []) == \
        ["delivered to the wrong robot"]
    (p,) = summarize([_row('{"checksum":false}', i, duplicates=i % 2) for i in range(6)])
    assert p["runs_broken"] == 0 and p["duplicates"] == 3


def test_a_quantile_is_reported_only_from_enough_runs():
    """p99 from 100 runs or more, p99.9 from 1000: with fewer the estimate would be the
    sample's maximum, and its bootstrap no interval. The report says what it needs."""
    few = summarize([_row('{"x":1}', i) for i in range(16)])[0]
    assert few["reform_p50_s"] is not None
    assert few["reform_p99_s"] is None and few["reform_p99.9_s"] is None
    many = summarize([_row('{"x":1}', i) for i in range(120)])[0]
    assert many["reform_p99_s"] is not None and many["reform_p99.9_s"] is None
    est, lo, hi = many["reform_p99_s"]
    assert lo <= est <= hi <= 2.2


def test_the_report_says_a_quantile_needs_more_runs(tmp_path, capsys):
    from hil.cli import main
    store = Store(tmp_path / "q.sqlite")
    store.add([_row('{"x":1}', i) for i in range(16)], "c0ffee", False)
    store.close()
    assert main(["campaign", "report", str(tmp_path / "q.sqlite")]) == 0
    out = capsys.readouterr().out
    assert "longest re-formation p50: " in out
    assert "longest re-formation p99: needs 100 runs with a re-formation, the point has 16" \
        in out
    assert "p99.9: needs 1000 runs" in out


def test_the_report_names_the_fixed_keys_once_and_tabulates_the_varying_ones(tmp_path,
                                                                            capsys):
    """Two points that differ only in ``ber``: ``robots`` and ``load`` are said once, the
    table has a ``ber`` column with one row a point (its runs, the failure rate with its
    interval), and each point's lines are headed by its ``ber`` alone."""
    from hil.cli import main
    store = Store(tmp_path / "t.sqlite")
    a, b = '{"ber":0.0,"load":1.0,"robots":"1,2"}', '{"ber":0.001,"load":1.0,"robots":"1,2"}'
    store.add([_row(a, i) for i in range(5)] + [_row(b, i, failed=2) for i in range(5)],
              "c0ffee", False)
    store.close()
    assert main(["campaign", "report", str(tmp_path / "t.sqlite")]) == 0
    out = capsys.readouterr().out
    assert out.count('load=1.0 robots=1,2') == 1 and "every point: " in out
    head = next(ln for ln in out.splitlines() if "failed rate" in ln)
    assert head.split()[0] == "ber" and "robots" not in head
    rows = [ln.split() for ln in out.splitlines() if ln.split()[:2] in (["0.0", "5"],
                                                                         ["0.001", "5"])]
    assert [r[0] for r in rows] == ["0.0", "0.001"]
    assert rows[1][4] == "0.2000"                       # 10 of 50 messages failed
    assert "\nber=0.001: 5 runs" in out and "\nber=0.0: 5 runs" in out
    assert '{"ber"' not in out


def _report_and_runs(store):
    """{point key: the report's point} and {point key: its runs}, keys canonical."""
    from collections import defaultdict
    runs = defaultdict(list)
    for r in store.rows():
        runs[json.dumps(json.loads(r["point_key"]), sort_keys=True)].append(r)
    report = {json.dumps(p["point"], sort_keys=True): p for p in summarize(store.rows())}
    return report, runs


def test_a_points_numbers_are_what_its_runs_traces_say(spec_file, tmp_path):
    """The report's counts for each point, recomputed by hand from the events of each of its
    runs run again alone (the same arguments and seed, every event kept): messages submitted
    and failed, the failure rate and its Wilson interval."""
    from hil.campaign.runs import sim_config_for
    from hil.sim import events as E
    from hil.sim.world import World
    spec = load_spec(spec_file, check=check_args)
    store = Store(tmp_path / "h.sqlite")
    _run_in_process(spec, store)
    report, by_point = _report_and_runs(store)
    assert len(report) == len(by_point) == 2
    for key, runs in by_point.items():
        submitted = failed = 0
        for r in runs:
            evs: list = []
            World(sim_config_for(r["args"], r["seed"]), listeners=[evs.append]).run()
            submitted += sum(type(e) is E.Submit for e in evs)
            failed += sum(type(e) is E.Failed for e in evs)
        p = report[key]
        assert (p["runs"], p["messages"], p["failed"]) == (len(runs), submitted, failed)
        assert submitted > 0
        assert p["failed_rate"] == failed / submitted
        assert p["failed_ci95"] == wilson(failed, submitted)


def test_message_latency_and_throughput_per_point_with_their_intervals(spec_file, tmp_path):
    """Each run records its delivered messages' latencies (a histogram, ms from submission to
    the last acknowledgement) and its throughput; the report pools the point's histograms
    (each quantile only from enough messages) and averages the throughput, each with a
    bootstrap interval over runs. Checked against the runs' events by hand."""
    from hil.campaign.report import pooled_quantile
    from hil.campaign.runs import sim_config_for
    from hil.sim import events as E
    from hil.sim.world import World
    spec = load_spec(spec_file, check=check_args)
    store = Store(tmp_path / "l.sqlite")
    _run_in_process(spec, store)
    report, by_point = _report_and_runs(store)
    for key, runs in by_point.items():
        p = report[key]
        latencies, tputs = [], []
        for r in runs:
            evs: list = []
            cfg = sim_config_for(r["args"], r["seed"])
            World(cfg, listeners=[evs.append]).run()
            sent = {(e.src, e.num): e.t for e in evs if type(e) is E.Submit}
            done = [e for e in evs if type(e) is E.Delivered]
            latencies += [(e.t - sent[(e.src, e.num)]) * 1000 // 16_000_000 for e in done]
            tputs.append(len(done) / cfg.duration)
        assert p["latency_messages"] == len(latencies) > 2
        median = pooled_quantile([{str(v): 1} for v in latencies], 0.5)
        est, lo, hi = p["latency_p50_ms"]
        assert est == median and lo <= est <= hi
        assert p["latency_p99_ms"] is None              # fewer than 100 messages
        est, lo, hi = p["throughput"]
        assert est == round(sum(tputs) / len(tputs), 4) and lo <= est <= hi


def _stored(db, damage: str | None = None) -> None:
    """A results file holding one campaign and one run, without running it; ``damage``: an
    SQL ``SET`` clause that then edits the run's row by hand."""
    store = Store(db)
    store.claim("x", 0)
    store.add([dict(run_key="k1", point_key='{"load":"1"}', args=["--load", "1"],
                    seed_index=0, seed=1, status="ok", error=None,
                    metrics={"submitted": 3, "delivered": 3, "failed": 0, "pending": 0,
                             "duplicates": 0, "misdelivered": 0, "corrupted_acted_on": 0,
                             "collisions": 0, "membership_changes": 4, "reformations": 0,
                             "reform_max_s": None, "not_reformed": 0,
                             "latency_ms": {"40": 3}, "throughput": 0.3},
                    wall_s=0.1, worker="w")], "c0ffee", False)
    store.close()
    if damage is not None:
        import sqlite3
        con = sqlite3.connect(db)
        con.execute(f"UPDATE runs SET {damage}")
        con.commit()
        con.close()


@pytest.mark.parametrize("damage", [
    "metrics = 'garbage'", "metrics = '{}'", "metrics = 'null'", "args = 'not json'",
    "point_key = 'xx'", "status = 'weird'", "status = NULL",
    "metrics = json_set(metrics, '$.submitted', 'x')",
    "metrics = json_set(metrics, '$.failed', json('null'))",
    "metrics = json_set(metrics, '$.reform_max_s', 'x')",
    "metrics = json_set(metrics, '$.latency_ms', json('[1, 2]'))",
    "metrics = json_set(metrics, '$.latency_ms', json('{\"a\": 1}'))",
    "metrics = json_set(metrics, '$.throughput', 'x')",
    "metrics = json_set(metrics, '$.delivered', 'x')",
    "metrics = json_set(metrics, '$.membership_changes', 'x')",
    "metrics = json_set(metrics, '$.custom', json('{\"m\": \"x\"}'))"])
@pytest.mark.parametrize("command", ["report", "export"])
def test_a_damaged_results_row_is_one_line_naming_it(tmp_path, capsys, damage, command):
    """Rows edited by hand made ``campaign report`` and ``export`` die in a JSONDecodeError,
    KeyError or TypeError traceback; so did a metric of the wrong type."""
    from hil.cli import main
    db = tmp_path / "m.sqlite"
    _stored(db, damage)
    extra = ["--csv", str(tmp_path / "m.csv")] if command == "export" else []
    code = main(["campaign", command, str(db), *extra])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "run k1: a damaged row" in err, err


@pytest.mark.parametrize("damage", ["status = 'weird'", "status = NULL"])
def test_a_status_no_run_has_is_one_line_in_campaign_status(tmp_path, capsys, damage):
    """``campaign status``, which counts the runs by status, died in a KeyError on a status
    no run stores."""
    from hil.cli import main
    db = tmp_path / "m.sqlite"
    _stored(db, damage)
    spec = tmp_path / "x.toml"
    spec.write_text('[campaign]\nname = "x"\n[grid]\nload = ["1"]\n')
    code = main(["campaign", "status", str(spec), "--db", str(db)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "run k1: a damaged row" in err, err


@pytest.mark.parametrize("command", ["report", "export", "status"])
def test_a_file_with_no_campaign_in_it_is_refused_and_left_as_it_was(tmp_path, capsys,
                                                                     command):
    """``campaign report app.sqlite`` on another program's database answered with an empty
    report, exit 0, and added the campaign's tables to it; an empty file became a database."""
    import sqlite3
    from hil.cli import main
    other, empty = tmp_path / "app.sqlite", tmp_path / "empty.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE users (name)")
    con.commit()
    con.close()
    empty.write_bytes(b"")
    spec = tmp_path / "t.toml"
    spec.write_text(SPEC)
    for db in (other, empty):
        before = db.read_bytes()
        args = {"report": [str(db)], "export": [str(db), "--csv", str(tmp_path / "o.csv")],
                "status": [str(spec), "--db", str(db)]}[command]
        code = main(["campaign", command, *args])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "no campaign in it" in err, err
        assert db.read_bytes() == before
    assert not (tmp_path / "o.csv").exists()


def _stored_before_the_code_column(db):
    """A results file of one run as written before runs had a ``code`` column."""
    import sqlite3
    _stored(db)
    con = sqlite3.connect(db)
    con.execute("ALTER TABLE runs DROP COLUMN code")
    con.commit()
    con.close()
    return db


@pytest.mark.parametrize("schema", ["CREATE TABLE runs (a, b)", "CREATE TABLE foo (x)",
                                    "CREATE TABLE meta (key, value)"])
def test_campaign_run_refuses_another_programs_database_and_leaves_it_as_it_was(tmp_path,
                                                                                schema):
    """``campaign run --db other.sqlite`` on a file with a ``runs`` table of its own died in a
    traceback (no such column) after adding a ``code`` column and a ``meta`` table to it; a
    file with other tables got the campaign's beside them. Refused in one line now, before
    anything is written; an empty file, and a campaign's own file from before the ``code``
    column, are still taken."""
    import sqlite3
    db = tmp_path / "other.sqlite"
    con = sqlite3.connect(db)
    con.execute(schema)
    con.commit()
    con.close()
    before = db.read_bytes()
    with pytest.raises(StoreError, match=r"not a campaign results file \(it holds other "
                       r"tables: .*\): give --db another file"):
        Store(db)
    assert db.read_bytes() == before
    Store(tmp_path / "new.sqlite").close()
    old = _stored_before_the_code_column(tmp_path / "old.sqlite")
    store = Store(old)
    assert len(store.rows()) == 1 and store.rows()[0]["code"] is None


@pytest.mark.parametrize("grid", ['duration = [1, 1.0]', 'robots = ["0,1", "00,1"]',
                                  'load = [1, "1"]'])
def test_one_point_spelled_two_ways_is_refused(tmp_path, grid):
    """``duration = [0.5, 0.50]`` was refused as a point given twice, ``[1, 1.0]`` not: the
    points are compared by the run they make."""
    from hil.campaign.spec import SpecError
    p = tmp_path / "d.toml"
    p.write_text(f'[campaign]\nname = "x"\nseeds = 2\nduration = 1\n[grid]\n{grid}\n')
    with pytest.raises(SpecError, match="make the same run"):
        load_spec(p, check=check_args)


def test_a_results_file_from_before_the_code_column_is_reported_as_it_is(tmp_path, capsys):
    """Reading opens the file read-only, so it no longer adds the ``code`` column a file
    written before it lacks: its rows read with no code, and the file is left as it was."""
    from hil.cli import main
    db = _stored_before_the_code_column(tmp_path / "old.sqlite")
    before = db.read_bytes()
    rows = Store(db, read_only=True).rows()
    assert len(rows) == 1 and rows[0]["code"] is None and rows[0]["metrics"]["submitted"] == 3
    assert main(["campaign", "report", str(db)]) == 0
    assert "1 runs" in capsys.readouterr().out
    assert db.read_bytes() == before


def test_the_metrics_the_report_reads_are_those_a_run_stores():
    """A row whose metrics lack one the report reads is refused as damaged (report died in a
    KeyError): the set is what metrics_of writes."""
    from hil.campaign.runs import metrics_of
    from hil.campaign.store import READ_METRICS
    from hil.sim.world import SimConfig
    assert READ_METRICS <= metrics_of(SimConfig(robots=(1, 2), duration=1.0)).keys()


def test_a_results_file_the_disk_cannot_take_more_of_stops_the_run_in_one_line(tmp_path):
    """A campaign whose results file stopped growing (the disk filled; here the process's
    file-size limit) died in an ``sqlite3.OperationalError`` traceback. It stops with one
    line and status 1, the runs stored before are kept, and ``campaign run`` again, with
    room, goes on from them."""
    import resource
    spec = tmp_path / "full.toml"
    spec.write_text('[campaign]\nname = "full"\nseeds = 40\nduration = 1\nchunk = 1\n'
                    '[grid]\nrobots = ["1,2"]\nber = [0.0, 0.001]\n')
    run = [sys.executable, "-m", "hil.cli", "campaign", "run", str(spec), "--workers", "1",
           "--no-progress", "--allow-dirty"]

    def limited():
        resource.setrlimit(resource.RLIMIT_FSIZE, (48 * 512, 48 * 512))
    r = subprocess.run(run, cwd=ROOT, capture_output=True, text=True, timeout=600,
                       preexec_fn=limited)
    errors = [line for line in r.stderr.splitlines() if line.startswith("rprs: error:")]
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert len(errors) == 1 and "cannot store results" in errors[0], r.stderr
    store = Store(tmp_path / "full.sqlite", read_only=True)
    kept = store.counts()["ok"]
    store.close()
    assert 0 < kept < 80
    r = subprocess.run(run, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert f"{kept} already in" in r.stdout and f"{80 - kept} run now" in r.stdout


def test_a_grid_key_of_numbers_and_words_exports_to_parquet_as_text(tmp_path, capsys):
    """``load = [1, "saturate"]`` ran, reported and exported to CSV, and ``export --parquet``
    died in pyarrow's ArrowTypeError: a Parquet column has one type."""
    pq = pytest.importorskip("pyarrow.parquet", reason="pyarrow not installed (the "
                             "'campaign' extra)")
    from hil.cli import main
    db = tmp_path / "m.sqlite"
    store = Store(db)
    store.claim("m", 0)
    rows = []
    for i, (load, flag) in enumerate(((1, True), ("saturate", 2))):
        rows.append(dict(run_key=f"k{i}", point_key=json.dumps({"load": load, "x": flag}),
                         args=["--load", str(load)], seed_index=0, seed=1, status="ok",
                         error=None, wall_s=0.1, worker="w",
                         metrics={"submitted": 3, "failed": 0, "duplicates": 0,
                                  "misdelivered": 0, "corrupted_acted_on": 0,
                                  "not_reformed": 0, "reform_max_s": None,
                                  "throughput": 0.3 if i else 1}))
    store.add(rows, "c0ffee", False)
    store.close()
    out = tmp_path / "m.parquet"
    assert main(["campaign", "export", str(db), "--parquet", str(out)]) == 0, \
        capsys.readouterr().err
    t = {r["run_key"]: r for r in pq.read_table(out).to_pylist()}
    assert (t["k0"]["param_load"], t["k1"]["param_load"]) == ("1", "saturate")
    assert (t["k0"]["param_x"], t["k1"]["param_x"]) == ("True", "2")
    assert (t["k0"]["m_throughput"], t["k1"]["m_throughput"]) == (1.0, 0.3)   # (floats)


def test_a_stop_signal_while_the_cluster_starts_is_handled_once_it_has_started():
    """Ctrl-C in the second or two Dask takes to start the embedded cluster interrupted the
    start, and Dask's shutdown of its half-started worker processes printed tracebacks
    ("Nanny failed to start") after ``rprs: interrupted``. The signal is held while the
    cluster starts, then handled as it would have been."""
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with engine.signals_held():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            reached.append("the start went on")
    assert reached == ["the start went on"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_second_run_of_a_campaign_on_its_results_file_is_refused_while_the_first_runs(
        spec_file, tmp_path, capsys):
    """Two ``campaign run`` of one campaign on one results file both ran every run, each
    printing "N run now", and one copy of each run was dropped: the work done twice. The
    second is refused in one line while the first holds the file; readers are not."""
    import fcntl
    from hil.cli import main
    db = tmp_path / "t.sqlite"
    Store(db).close()
    with open(db, "rb") as held:               # as a first campaign run holds it
        fcntl.flock(held.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        code = main(["campaign", "run", str(spec_file), "--db", str(db), "--workers", "1",
                     "--no-progress"])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1, err
        assert f"another campaign run is writing {db}" in err
        assert main(["campaign", "status", str(spec_file), "--db", str(db)]) == 0
    assert db.exists()
