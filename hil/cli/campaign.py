"""``rprs campaign run|report|export``: thousands of seeded simulator runs on Dask, their
results in SQLite, statistics with confidence intervals (hil/campaign, docs/campaigns.md)."""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from .common import UserError, distinct_outputs, file_name, stderr_console


def _db_for(spec_path: str, db: str | None) -> str:
    return db or str(Path(spec_path).with_suffix(".sqlite"))


def _check_scheduler(address: str) -> None:
    """A Dask scheduler address Dask can parse (scheme known, host and port for TCP), checked
    before the results file is made: a UserError otherwise."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend
    try:
        scheme, loc = parse_address(address)
        get_backend(scheme)
        if scheme in ("tcp", "tls", "ws", "wss"):
            parse_host_port(loc)
    except ValueError as e:
        raise UserError(f"--scheduler {address}: {e} (e.g. tcp://HOST:8786)") from None


def cmd_run(a: argparse.Namespace) -> int:
    from ..campaign.engine import run_campaign
    from ..campaign.runs import check_args
    from ..campaign.spec import SpecError, load_spec
    from ..campaign.store import Store, StoreError
    if a.workers is not None and a.workers < 1:
        raise UserError("--workers must be at least 1")
    if a.retries < 0:
        raise UserError(f"--retries must be 0 or more, got {a.retries}")
    if a.scheduler:
        _check_scheduler(a.scheduler)
    try:
        spec = load_spec(a.spec, check=check_args)
    except SpecError as e:
        raise UserError(str(e)) from None
    db = _db_for(a.spec, a.db)
    new_file = not Path(db).exists()
    try:
        store = Store(db)
    except StoreError as e:
        raise UserError(str(e)) from None
    try:
        lock = _only_run_on(db)
    except UserError:
        store.close()
        raise
    try:
        return _run_into(a, spec, store, db, run_campaign)
    except (UserError, KeyboardInterrupt):
        if new_file and not any(store.counts().values()):
            # refused or stopped before any run was stored (a dirty tree, no scheduler,
            # Ctrl-C while the cluster started): no empty file left
            store.close()
            Path(db).unlink(missing_ok=True)
        raise
    finally:
        store.close()
        if lock is not None:
            os.close(lock)


def _only_run_on(db: str) -> int | None:
    """Take ``db`` for this ``campaign run`` alone (an exclusive ``flock`` on the file, which
    SQLite's own locks leave alone): a second run of the same campaign on it did every run
    again, and one of the two copies of each was dropped. Readers (``status``, ``report``)
    are not held off. The descriptor that holds it, or None where there is no ``flock``."""
    try:
        import fcntl
    except ImportError:                       # (not on Windows)
        return None
    fd = os.open(db, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise UserError(f"another campaign run is writing {db}: wait for it to end, or give "
                        f"this one another --db") from None
    return fd


def _run_into(a: argparse.Namespace, spec, store, db: str, run_campaign) -> int:
    """``campaign run``'s run into ``store`` (``db``), with its progress bar."""
    from ..campaign.store import StoreError, StoreWriteError
    progress = None
    bar = None
    if not a.no_progress and sys.stderr.isatty():
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn
        # the time left is the runs left at the rate shown beside it (rich's own estimate,
        # from the few updates a chunk of runs gives, disagreed with that rate 2-4x)
        bar = Progress(TextColumn(f"campaign {spec.name}"), BarColumn(), MofNCompleteColumn(),
                       TextColumn("{task.fields[rate]} runs/s, {task.fields[left]} left"),
                       console=stderr_console(), transient=True)
        task = bar.add_task("runs", total=None, rate="-", left="-:--:--")
        import time
        t0 = time.perf_counter()

        def progress(done: int, total: int) -> None:
            dt = time.perf_counter() - t0
            rate = done / dt if dt > 0 else 0.0
            left = "-:--:--"
            if rate > 0:
                s = round((total - done) / rate)
                left = f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"
            bar.update(task, completed=done, total=total,
                       rate=f"{rate:.1f}" if dt > 0 else "-", left=left)
        bar.start()
    try:
        out = run_campaign(spec, store, scheduler=a.scheduler, workers=a.workers,
                           allow_dirty=a.allow_dirty, on_progress=progress,
                           retries=a.retries,
                           on_dashboard=lambda link: print(f"campaign {spec.name}: Dask "
                                                           f"dashboard {link}",
                                                           file=sys.stderr, flush=True),
                           on_workers=lambda n: print(
                               f"campaign {spec.name}: " + (
                                   "no worker is connected: the runs wait until one joins "
                                   "(Ctrl-C stops; campaign run again goes on from there)"
                                   if n == 0 else f"{n} worker(s) connected again"),
                               file=sys.stderr, flush=True))
    except StoreWriteError as e:          # (the disk filled while it ran: it cannot go on)
        print(f"rprs: error: {e}", file=sys.stderr)
        return 1
    except StoreError as e:
        raise UserError(str(e)) from None
    except OSError as e:
        raise UserError(f"cannot reach the Dask scheduler {a.scheduler}: {e}") from None
    finally:
        if bar is not None:
            bar.stop()
    print(f"campaign {spec.name}: {out.planned} runs planned, {out.skipped} already in {db}, "
          f"{out.ran} run now ({out.crashed} crashed) in {out.wall_s:.1f} s on "
          f"{out.workers} worker(s)"
          + (f" ({out.workers_end} at the end)" if out.workers_end != out.workers else "")
          + f", {out.chunks} chunks; time not in runs "
          f"{out.overhead * 100:.1f} %")
    if out.retried or out.lost:
        print(f"the cluster lost tasks: {out.retried} run(s) sent again, {out.lost} lost on "
              f"every try (stored as lost, not as results: run the campaign again to run "
              f"them)")
    return 1 if out.lost else 0


def cmd_status(a: argparse.Namespace) -> int:
    """What a campaign's results file holds against its file, running nothing."""
    from ..campaign.runs import check_args
    from ..campaign.seeds import run_key
    from ..campaign.spec import SpecError, load_spec
    from ..campaign.store import Store, StoreError
    try:
        spec = load_spec(a.spec, check=check_args)
    except SpecError as e:
        raise UserError(str(e)) from None
    db = _db_for(a.spec, a.db)
    if Path(db).is_dir():
        raise UserError(f"{db} is a directory, not a campaign results file")
    if not Path(db).is_file():
        print(f"campaign {spec.name}: {spec.runs} runs, none done yet (no {db})")
        return 0
    mine = {run_key(p.key, i) for p in spec.points for i in range(spec.seeds)}
    try:
        store = Store(db, read_only=True)
        try:
            store.holds(spec.name, spec.root_seed)   # another campaign's file: refused, as
            counts, done = store.counts(mine), store.done()     # by run
        finally:
            store.close()
    except StoreError as e:
        raise UserError(str(e)) from None
    missing = len(mine - done)
    print(f"campaign {spec.name} in {db}: {spec.runs} runs; done {counts['ok']}, crashed "
          f"{counts['crashed']} (the model raised: results), lost {counts['lost']} (the "
          f"cluster lost them: to run again), missing {missing}")
    return 0


def cmd_report(a: argparse.Namespace) -> int:
    from ..campaign.report import (LATENCY_QUANTILES, REFORM_QUANTILES, fixed_and_varying,
                                   plot, point_label, summarize)
    from ..campaign.store import Store, StoreError
    if not Path(a.db).is_file():
        raise UserError(f"no results file {a.db}")
    try:
        store = Store(a.db, read_only=True)
        rows = store.rows()
    except StoreError as e:
        raise UserError(str(e)) from None
    points = summarize(rows)
    if a.plots:
        try:
            files = plot(points, rows, a.plots)
        except OSError as e:
            raise UserError(f"cannot write plots into {a.plots}: {e.strerror}") from None
    else:
        files = []
    if a.json:
        print(json.dumps({"points": points, "plots": files}, indent=1))
        return 0
    meta = store.meta()
    lost = sum(1 for r in rows if r["status"] == "lost")
    print(f"campaign {meta.get('name', '?')} (root seed {meta.get('root_seed', '?')}): "
          f"{len(rows) - lost} runs, {sum(p['crashed'] for p in points)} crashed"
          + (f"; {lost} lost by the cluster, left out (campaign run runs them again)"
             if lost else ""))
    fixed, varying = fixed_and_varying(points)
    if fixed:
        print(f"every point: {point_label(fixed)}")
    if points:
        _report_table(points, varying)
    for p in points:
        label = point_label({k: p["point"].get(k) for k in varying}) if varying else \
            "the point"
        print(f"\n{label}: {p['runs']} runs")
        if p["failed_rate"] is not None:
            lo, hi = p["failed_ci95"]
            print(f"  messages failed: {p['failed']}/{p['messages']} = "
                  f"{p['failed_rate']:.4f} (95 % CI {lo:.4f}-{hi:.4f})")
        if p["corrupted_acted_on"]:
            print(f"  corrupted commands acted on: {p['corrupted_acted_on']}")
        lo, hi = p["runs_broken_ci95"]
        print(f"  runs that broke an invariant or crashed: {p['runs_broken']}/{p['runs']} "
              f"(95 % CI {lo:.3f}-{hi:.3f})")
        if p.get("throughput"):
            v = p["throughput"]
            print(f"  delivered throughput: {v[0]:g} messages/s (95 % CI {v[1]:g}-{v[2]:g}, "
                  f"mean of {p['runs'] - p['crashed']} runs)")
        for name, (est, lo, hi, n) in p.get("custom", {}).items():
            print(f"  {name}: {est:g} (95 % CI {lo:g}-{hi:g}, mean of {n} runs)")
        _quantile_lines(p, "message latency", "latency_{}_ms", "ms", "delivered messages",
                        "messages", p.get("latency_messages", 0), LATENCY_QUANTILES)
        if p.get("duplicates"):
            print(f"  messages delivered twice: {p['duplicates']}"
                  + ("" if p["point"].get("checksum") else " (without the checksum no "
                     "invariant promises none: docs/guarantees.md)"))
        _quantile_lines(p, "longest re-formation", "reform_{}_s", "s", "runs with a "
                        "re-formation", "runs", p["reform_runs"], REFORM_QUANTILES)
        for f in p["failing"]:
            print(f"  FAILED ({', '.join(f['broke'])}): {f['command']}")
            if f.get("error"):
                print(f"    it raised: {f['error']}")
    for f in files:
        print(f"plot: {f}")
    return 0


def _report_table(points: list[dict], varying: list[str]) -> None:
    """One row a point: the grid keys that vary, then its runs, the runs that broke an
    invariant or crashed, the failure rate, throughput, message latency p50/p95 and the
    longest re-formation's p50, each with its 95 % interval ("-": no sample; "needs N": too
    few for the quantile). The lines after it give every figure in words."""
    from rich import box
    from rich.table import Table

    from ..campaign.report import runs_for
    from .common import stdout_console

    def est(v, q: float | None = None, fmt: str = "{:g}") -> str:
        if v is None:
            return f"needs {runs_for(q)}" if q is not None else "-"
        return f"{fmt.format(v[0])} ({fmt.format(v[1])}-{fmt.format(v[2])})"

    t = Table(box=box.SIMPLE, show_edge=False)
    for k in varying:
        t.add_column(k)
    for name in ("runs", "broken", "failed rate", "messages/s", "latency p50 ms",
                 "latency p95 ms", "re-formation p50 s"):
        t.add_column(name, justify="right")
    for p in points:
        lo, hi = p["failed_ci95"]
        failed = "-" if p["failed_rate"] is None else \
            f"{p['failed_rate']:.4f} ({lo:.4f}-{hi:.4f})"
        blo, bhi = p["runs_broken_ci95"]
        t.add_row(*[json.dumps(p["point"].get(k)) if not isinstance(p["point"].get(k), str)
                    else p["point"][k] for k in varying],
                  str(p["runs"]), f"{p['runs_broken']} ({blo:.3f}-{bhi:.3f})", failed,
                  est(p.get("throughput")),
                  est(p.get("latency_p50_ms"), 0.5) if "latency_p50_ms" in p else "-",
                  est(p.get("latency_p95_ms"), 0.95) if "latency_p95_ms" in p else "-",
                  est(p.get("reform_p50_s"), 0.5) if "reform_p50_s" in p else "-")
    stdout_console().print(t)


def _quantile_lines(p: dict, what: str, key: str, unit: str, of: str, samples: str,
                    n: int, qs: tuple[float, ...]) -> None:
    """A report's quantile lines for one point: each estimate with its interval, or how many
    samples it needs (campaign/report.py, ``runs_for``)."""
    from ..campaign.report import quantile_name, runs_for
    for q in qs:
        name = quantile_name(q)
        v = p.get(key.format(name), "absent")
        if v == "absent":
            continue
        if v is None:
            print(f"  {what} {name}: needs {runs_for(q)} {of}, the point has {n}")
        else:
            print(f"  {what} {name}: {v[0]:g} {unit} (95 % CI {v[1]:g}-{v[2]:g}, {n} "
                  f"{samples})")


def cmd_export(a: argparse.Namespace) -> int:
    from ..campaign.store import Store, StoreError
    if not Path(a.db).is_file():
        raise UserError(f"no results file {a.db}")
    if not (a.csv or a.parquet):
        raise UserError("give --csv FILE and/or --parquet FILE")
    distinct_outputs(csv=a.csv, parquet=a.parquet)
    for opt, path in (("csv", a.csv), ("parquet", a.parquet)):
        if path and Path(path).resolve() == Path(a.db).resolve():
            raise UserError(f"--{opt} names the results file {a.db} itself, which the export "
                            f"would overwrite: give another file")
    try:
        store = Store(a.db, read_only=True)
        for path, fn in ((a.csv, store.export_csv), (a.parquet, store.export_parquet)):
            if path:
                print(f"{fn(path)} runs -> {path}")
    except StoreError as e:
        raise UserError(str(e)) from None
    except OSError as e:
        raise UserError(f"cannot write {e.filename}: {e.strerror}") from None
    return 0


def add(sub) -> None:
    ca = sub.add_parser("campaign", help="many seeded simulator runs on Dask, with statistics")
    csub = ca.add_subparsers(dest="campaign_command", metavar="ACTION", required=True,
                             parser_class=type(ca))
    r = csub.add_parser("run", help="run every missing (grid point, seed) of a campaign file")
    r.add_argument("spec", metavar="SPEC.toml", help="the campaign file (docs/campaigns.md)")
    r.add_argument("--db", type=file_name, metavar="FILE",
                   help="the results file (default: SPEC.sqlite)")
    r.add_argument("--scheduler", metavar="tcp://HOST:8786", help="a running Dask scheduler "
                   "(default: a local cluster, one worker per core)")
    r.add_argument("--workers", type=int, help="local cluster: worker processes (default: "
                   "one per core); with --scheduler: wait until that many workers joined")
    r.add_argument("--allow-dirty", action="store_true", help="run from a tree with "
                   "uncommitted changes, or add to results of another commit")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.add_argument("--retries", type=int, default=2, metavar="N",
                   help="send a task the cluster lost (a worker died) again up to N times "
                        "before its runs are stored as lost (default: 2)")
    r.set_defaults(func=cmd_run)
    st = csub.add_parser("status", help="done, crashed, lost and missing runs of a campaign, "
                         "running nothing")
    st.add_argument("spec", metavar="SPEC.toml", help="the campaign file")
    st.add_argument("--db", type=file_name, metavar="FILE",
                    help="the results file (default: SPEC.sqlite)")
    st.set_defaults(func=cmd_status)
    rep = csub.add_parser("report", help="per grid point: rates with Wilson intervals, "
                          "re-formation quantiles, the failing runs as commands")
    rep.add_argument("db", metavar="RESULTS.sqlite")
    rep.add_argument("--plots", type=file_name, metavar="DIR", help="write PNG plots into DIR")
    rep.add_argument("--json", action="store_true", help="print the statistics as JSON")
    rep.set_defaults(func=cmd_report)
    ex = csub.add_parser("export", help="the runs as CSV or Parquet (pandas, DuckDB)")
    ex.add_argument("db", metavar="RESULTS.sqlite")
    ex.add_argument("--csv", type=file_name, metavar="FILE",
                    help="one row a run: the columns, each grid "
                    "parameter (param_*) and each metric (m_*)")
    ex.add_argument("--parquet", type=file_name, metavar="FILE",
                    help="the same rows as Parquet (needs "
                    "pyarrow)")
    ex.set_defaults(func=cmd_export)
