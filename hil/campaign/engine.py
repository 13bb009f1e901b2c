"""Running a campaign on Dask distributed (docs/campaigns.md).

The embedded default is a ``LocalCluster`` with one single-threaded worker process per core;
``scheduler="tcp://HOST:8786"`` runs the same campaign on a real cluster (``dask scheduler`` /
``dask worker``, or dask-jobqueue on Slurm/PBS). Runs already in the results file are skipped
(run-missing); results from another commit, or from a tree with uncommitted changes, are not
mixed unless ``allow_dirty``. Runs go to the workers in chunks; the rows come back to this
process, which alone writes the SQLite file, chunk by chunk (a killed campaign loses at most
the chunks in flight).
"""
from __future__ import annotations

import contextlib
import math
import os
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

from .code import code_identity
from .runs import metrics_of, run_chunk
from .seeds import run_key, run_seed
from .spec import Spec
from .store import Store, StoreError

SOURCE = Path(__file__).resolve().parents[2]


def source_state(root: Path = SOURCE) -> tuple[str, bool]:
    """(commit, dirty) of the project's source: the git commit, and whether tracked files
    differ from it. Not a git checkout (an installed package): ("rprs <version>", False)."""
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"],
                                capture_output=True, text=True, timeout=10, check=True
                                ).stdout.strip()
        status = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                 "--untracked-files=no"], capture_output=True, text=True,
                                timeout=10, check=True).stdout
        return commit, bool(status.strip())
    except (OSError, subprocess.SubprocessError):
        from importlib.metadata import PackageNotFoundError, version
        try:
            return f"rprs {version('rprs')}", False
        except PackageNotFoundError:
            return "unknown", False


@dataclass
class Outcome:
    planned: int
    skipped: int
    ran: int
    crashed: int
    wall_s: float
    task_s: float
    chunks: int
    workers: int = 1
    lost: int = 0
    """Runs the cluster lost (a worker's death, a scheduler restart) on every try: stored as
    ``lost``, not as results; the next ``campaign run`` runs them again."""
    retried: int = 0
    """Runs whose task was lost and sent again."""
    workers_end: int = 1
    """Workers connected when the last run came back (one that died is not counted)."""

    @property
    def overhead(self) -> float:
        """Share of the workers' time (wall time x workers) not spent inside runs: scheduling,
        transfers, the database, and workers idle at the end for want of work."""
        if self.wall_s <= 0:
            return 0.0
        return max(0.0, 1.0 - self.task_s / (self.wall_s * self.workers))


def plan(spec: Spec, done: set[str]) -> list[tuple]:
    """Every (run key, point key, args, index, seed) of ``spec`` not in ``done``."""
    items = []
    for p in spec.points:
        for i in range(spec.seeds):
            k = run_key(p.key, i)
            if k not in done:
                items.append((k, p.key, p.args, i, run_seed(spec.root_seed, p.key, i)))
    return items


def chunked(items: list, workers: int, chunk: int = 0) -> list[list]:
    """Split into chunks: ``chunk`` runs each, or by default about 4 chunks per worker, at
    most 25 runs a chunk (a killed campaign then loses little)."""
    if not items:
        return []
    n = chunk or max(1, min(25, math.ceil(len(items) / (4 * max(1, workers)))))
    return [items[i:i + n] for i in range(0, len(items), n)]


def dashboard_available() -> bool:
    """Dask's dashboard needs bokeh (the ``campaign`` extra installs it)."""
    import importlib.util
    return importlib.util.find_spec("bokeh") is not None


def dashboard_link(client: Any) -> str | None:
    """The dashboard's address as the client gives it; for a scheduler in this process
    (``inproc://``) Dask names the machine's address, but the server listens on loopback
    (``local_cluster``)."""
    from urllib.parse import urlsplit, urlunsplit
    link = getattr(client, "dashboard_link", None)
    if link and str(getattr(client.scheduler, "address", "")).startswith("inproc://"):
        u = urlsplit(link)
        link = urlunsplit(u._replace(netloc=f"127.0.0.1:{u.port}"))
    return link


def local_cluster(workers: int, processes: bool = True, threads_per_worker: int = 1) -> Any:
    """The embedded ``LocalCluster``: its scheduler's HTTP server (the dashboard when bokeh is
    installed, else health and metrics only) on a free loopback port, never 8787: a fixed
    port (``dashboard_address=None`` alone still put the server on 0.0.0.0:8787) made a
    second cluster on the machine (two campaigns, or the tests' beside each other) find it
    taken: "Port 8787 is already in use" and a socket left open (ResourceWarning) by the
    failed bind.

    Its own logs are silenced up to CRITICAL: at shutdown a worker's heartbeat in flight when
    the scheduler closes logs "Failed to communicate with scheduler" at ERROR with two
    tracebacks, though every run has ended and is stored. A run that fails is reported in its
    row (``status``, ``error``), not by Dask's log."""
    import logging
    from dask.distributed import LocalCluster
    return LocalCluster(n_workers=workers, threads_per_worker=threads_per_worker,
                        processes=processes,
                        dashboard_address="127.0.0.1:0" if dashboard_available() else None,
                        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                        silence_logs=logging.CRITICAL)


class WorkerWatch:
    """Says when a cluster has no worker left (``on_change(0)``), and when workers are back
    (``on_change(n)``): with every worker gone a campaign waits for one to join and its
    progress stops, which without a word looks like a hang. Looks at the client's view of the
    scheduler (``scheduler_info()``, which Dask refreshes every few seconds) every
    ``every_s`` s, in a thread of its own, until ``stop()``."""

    def __init__(self, client: Any, on_change: Callable[[int], None],
                 every_s: float = 2.0) -> None:
        import threading
        self.client = client
        self.on_change = on_change
        self.every_s = every_s
        self.none = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="rprs-worker-watch",
                                        daemon=True)

    def start(self) -> "WorkerWatch":
        self._thread.start()
        return self

    def check(self) -> None:
        """One look: tell a change between no worker and some."""
        try:
            n = len(self.client.scheduler_info().get("workers", {}))
        except Exception:      # noqa: BLE001 - the client is closing: nothing to say
            return
        if (n == 0) != self.none:
            self.none = n == 0
            self.on_change(n)

    def _run(self) -> None:
        while not self._stop.wait(self.every_s):
            self.check()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5)


class CodeMismatch(StoreError):
    """A worker runs other code than the client (an edited copy, another checkout)."""


def check_workers(client: Any) -> None:
    """CodeMismatch unless every worker of ``client`` runs the client's code (the digest of
    the simulator's sources, hil/campaign/code.py: Dask's own version check covers the
    libraries, not this project)."""
    mine = code_identity()
    theirs = client.run(code_identity)
    other = {addr: digest for addr, digest in theirs.items() if digest != mine}
    if other:
        raise CodeMismatch(
            f"{len(other)} of {len(theirs)} worker(s) run other code than this client "
            f"(sources {', '.join(sorted(set(other.values())))} against {mine}): "
            + ", ".join(sorted(other)) + "; start them from this checkout")


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Hold the stop signals (SIGINT, SIGTERM, SIGHUP) while the embedded cluster starts, then
    handle the first that came as it would have been: one that interrupts ``LocalCluster``
    mid-start leaves its nannies half started, and Dask's shutdown of them at exit printed
    tracebacks ("Nanny failed to start") after ``rprs: interrupted``. A start takes a second
    or two; in the main thread only (where signals are handled)."""
    import signal
    import threading
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[tuple[int, Any]] = []
    old: dict[int, Any] = {}
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None and signal.getsignal(sig) not in (signal.SIG_IGN, None):
            old[sig] = signal.signal(sig, lambda signum, frame: came.append((signum, frame)))
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
    if came:                  # (not if the start itself raised: that goes on)
        signum, frame = came[0]
        handler = old[signum]
        if callable(handler):
            handler(signum, frame)            # Python's SIGINT handler raises KeyboardInterrupt
        else:
            os.kill(os.getpid(), signum)      # SIG_DFL: as it would have, now


RETRIES = 2
"""How many times a task the cluster lost is sent again before its runs are stored lost."""


def run_campaign(spec: Spec, store: Store, scheduler: str | None = None,
                 workers: int | None = None, allow_dirty: bool = False,
                 measure: Callable[[Any], dict] = metrics_of,
                 on_progress: Callable[[int, int], None] | None = None,
                 client: Any = None, retries: int = RETRIES,
                 on_dashboard: Callable[[str], None] | None = None,
                 on_workers: Callable[[int], None] | None = None) -> Outcome:
    """Run every missing (or lost) run of ``spec`` into ``store``. StoreError when results
    would mix commits or come from a dirty tree (unless ``allow_dirty``).

    A run that raises is a result (``crashed``, with its traceback). A task that fails
    instead (its worker died, the scheduler lost it: Dask's ``KilledWorker``) is no result:
    it is sent again up to ``retries`` times, then its runs are stored ``lost``, which the
    report leaves out and the next run of the campaign runs again. ``on_dashboard(link)``:
    the cluster's dashboard, once its workers are there (the embedded cluster's only with
    bokeh installed; an external scheduler's as it gives it). ``on_workers(n)``: the
    cluster has no worker left (n = 0) or has some again (``WorkerWatch``)."""
    if spec.metrics and measure is metrics_of:      # the campaign's own metrics too
        import functools
        measure = functools.partial(metrics_of, hook=spec.metrics)
    commit, dirty = source_state()
    if not allow_dirty:
        if dirty:
            raise StoreError("the source tree has uncommitted changes: commit them, or "
                             "--allow-dirty to run anyway (rows are marked dirty)")
        other = {c for c, d in store.commits() if c != commit or d}
        if other:
            raise StoreError(f"{store.path} holds runs made with {', '.join(sorted(other))}; "
                             f"this source is {commit}: use another --db, or --allow-dirty "
                             "to mix them")
    store.claim(spec.name, spec.root_seed)
    done = store.done()
    items = plan(spec, done)
    skipped = spec.runs - len(items)
    if not items:
        return Outcome(spec.runs, skipped, 0, 0, 0.0, 0.0, 0)
    own = client is None
    cluster = None
    watch: WorkerWatch | None = None
    try:
        if own:
            from dask.distributed import Client
            if scheduler:
                client = Client(scheduler, timeout="30s")
            else:
                with signals_held():
                    cluster = local_cluster(workers or os.cpu_count() or 1)
                    client = Client(cluster)
        from dask.distributed import as_completed
        if cluster is not None:
            client.wait_for_workers(workers or os.cpu_count() or 1, timeout=120)
        elif workers:                        # a real cluster: wait until that many joined
            client.wait_for_workers(workers, timeout=300)
        nworkers = max(1, len(client.scheduler_info().get("workers", {})) or (workers or 1))
        check_workers(client)
        if on_dashboard is not None and (cluster is None or dashboard_available()):
            link = dashboard_link(client)
            if link:
                on_dashboard(link)
        t0 = time.perf_counter()             # the runs' wall time, not the cluster's start
        chunks = chunked(items, nworkers, spec.chunk)
        futures = client.map(run_chunk, chunks, measure=measure, pure=False)
        watch = WorkerWatch(client, on_workers).start() if on_workers is not None else None
        ran = crashed = lost = retried = 0
        task_s = 0.0
        todo = {f.key: (c, 0) for f, c in zip(futures, chunks)}
        pending = as_completed(futures)
        for fut in pending:
            chunk, tries = todo.pop(fut.key)
            try:
                rows = fut.result()
            except Exception as e:    # noqa: BLE001 - the cluster lost the task, not a run
                if tries < retries:
                    again = client.submit(run_chunk, chunk, measure=measure, pure=False)
                    todo[again.key] = (chunk, tries + 1)
                    pending.add(again)
                    retried += len(chunk)
                    continue
                rows = [{"run_key": k, "point_key": pk, "args": list(a), "seed_index": i,
                         "seed": s, "status": "lost", "metrics": None, "wall_s": 0.0,
                         "worker": "?", "error": f"the cluster lost the task {tries + 1} "
                         f"time(s): {type(e).__name__}: {e}"} for k, pk, a, i, s in chunk]
            store.add(rows, commit, dirty)
            ran += len(rows)
            crashed += sum(1 for r in rows if r["status"] == "crashed")
            lost += sum(1 for r in rows if r["status"] == "lost")
            task_s += sum(r["wall_s"] for r in rows)
            if on_progress is not None:
                on_progress(ran, len(items))
        workers_end = len(client.scheduler_info().get("workers", {}))
    finally:
        if watch is not None:
            watch.stop()
        if own:
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()
    wall = time.perf_counter() - t0
    return Outcome(spec.runs, skipped, ran, crashed, wall, task_s, len(chunks), nworkers,
                   lost, retried, workers_end)
