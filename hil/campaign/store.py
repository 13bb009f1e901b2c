"""A campaign's results: one SQLite file, one row per run (docs/campaigns.md).

Table ``runs``: ``run_key`` (primary key: a run is stored once), ``point_key`` (the grid
point's canonical parameters, JSON), ``args`` (its ``rprs sim`` arguments, JSON), ``seed_index``,
``seed``, ``status`` (``ok``; ``crashed``: the model raised; ``lost``: the cluster lost the task,
no result, run again by the next ``campaign run``), ``error`` (the traceback of a crashed run),
``metrics`` (JSON), ``wall_s``, ``worker``, ``commit_id`` and ``dirty`` (the source the run
was made with), ``finished_at`` (UTC), ``code`` (the digest of the simulator's sources the
worker ran: hil/campaign/code.py). Table ``meta``: the campaign's name and root seed.
"""
from __future__ import annotations

import csv
import datetime
import io
import json
import sqlite3
from pathlib import Path
from typing import Any, Iterable

COLUMNS = ("run_key", "point_key", "args", "seed_index", "seed", "status", "error", "metrics",
           "wall_s", "worker", "commit_id", "dirty", "finished_at", "code")


READ_METRICS = frozenset({"submitted", "failed", "duplicates", "misdelivered",
                          "corrupted_acted_on", "not_reformed", "reform_max_s"})
"""The metrics of an ``ok`` run that the report and the verdicts read without a default
(hil/campaign/runs.py ``metrics_of`` writes them all): a row without one is damaged."""


OTHER_METRICS = frozenset({"delivered", "pending", "collisions", "membership_changes",
                           "reformations"})
"""The other numbers ``metrics_of`` writes, which ``export`` writes out and a report may
read: each, if there, a number (a row edited by hand to hold text in one is damaged)."""


STATUSES = frozenset({"ok", "crashed", "lost"})
"""A stored run's ``status`` (the module docstring)."""


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _sound_metrics(m: Any) -> bool:
    """Are an ``ok`` run's metrics what ``metrics_of`` writes, in what the report reads: every
    READ_METRICS entry a number (``reform_max_s`` None without a re-formation), each of
    OTHER_METRICS there a number, the latency
    histogram {number as text: count}, the throughput a number, the custom ones numbers?"""
    if not isinstance(m, dict) or not READ_METRICS <= m.keys():
        return False
    if not all(_number(m[k]) for k in READ_METRICS - {"reform_max_s"}) or not (
            m["reform_max_s"] is None or _number(m["reform_max_s"])):
        return False
    if not all(_number(m[k]) for k in OTHER_METRICS if k in m):
        return False
    lat = m.get("latency_ms")
    if lat is not None:
        if not isinstance(lat, dict) or not all(isinstance(n, int) and _number(n)
                                                for n in lat.values()):
            return False
        try:
            [float(k) for k in lat]
        except ValueError:
            return False
    if "throughput" in m and not _number(m["throughput"]):
        return False
    custom = m.get("custom")
    return custom is None or (isinstance(custom, dict) and all(_number(v)
                                                               for v in custom.values()))


class StoreError(ValueError):
    """A results file that cannot be opened or does not belong to this campaign."""


class StoreWriteError(StoreError):
    """Results that could not be stored while the campaign ran (the disk filled, the file
    became read-only): the rows stored before are kept."""


class Store:
    """``read_only``: a file to read (``campaign status``, ``report``, ``export``), which
    must exist and hold a campaign; nothing in it is created or changed."""

    def __init__(self, path: str | Path, read_only: bool = False) -> None:
        self.path = Path(path)
        if not self.path.parent.is_dir():
            raise StoreError(f"{path}: no directory {self.path.parent} to keep the results in")
        if self.path.is_dir():
            raise StoreError(f"{path} is a directory, not a campaign results file")
        if read_only:
            self._open_to_read()
            return
        try:
            self.db = sqlite3.connect(self.path)
            self._refuse_foreign()
            self.db.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT)")
            self.db.execute(
                "CREATE TABLE IF NOT EXISTS runs (run_key TEXT PRIMARY KEY, point_key TEXT, "
                "args TEXT, seed_index INTEGER, seed INTEGER, status TEXT, error TEXT, "
                "metrics TEXT, wall_s REAL, worker TEXT, commit_id TEXT, dirty INTEGER, "
                "finished_at TEXT, code TEXT)")
            have = {row[1] for row in self.db.execute("PRAGMA table_info(runs)")}
            if "code" not in have:          # a file from before the column: its rows' is NULL
                self.db.execute("ALTER TABLE runs ADD COLUMN code TEXT")
            self.db.commit()
            self._columns = set(COLUMNS)
        except sqlite3.DatabaseError as e:
            raise StoreError(f"{path}: not a campaign results file ({e})") from None

    def _refuse_foreign(self) -> None:
        """A file that holds tables but not a campaign's (``meta``, and ``runs`` with its
        columns) is someone else's database: refused, nothing in it changed (it used to get
        the campaign's tables beside its own, or a column added to its ``runs``)."""
        tables = {n for (n,) in self.db.execute(
            "SELECT name FROM sqlite_master WHERE type = 'table'")}
        if not tables:
            return
        columns = {row[1] for row in self.db.execute("PRAGMA table_info(runs)")}
        if "meta" not in tables or not set(COLUMNS) - {"code"} <= columns:
            self.db.close()
            raise StoreError(f"{self.path}: not a campaign results file (it holds other "
                             f"tables: {', '.join(sorted(tables))}): give --db another file")

    def _open_to_read(self) -> None:
        if not self.path.is_file():
            raise StoreError(f"no results file {self.path}")
        try:
            self.db = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro", uri=True)
            tables = {n for (n,) in self.db.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'")}
            columns = {row[1] for row in self.db.execute("PRAGMA table_info(runs)")}
        except sqlite3.DatabaseError as e:
            raise StoreError(f"{self.path}: not a campaign results file ({e})") from None
        self._columns = columns        # (a file from before the code column is read as is)
        if "meta" not in tables or not {"run_key", "point_key", "metrics"} <= columns:
            self.db.close()
            raise StoreError(f"{self.path}: not a campaign results file (no campaign in it)")

    def close(self) -> None:
        self.db.close()

    # -- meta -------------------------------------------------------------------------------
    def meta(self) -> dict[str, str]:
        return dict(self.db.execute("SELECT key, value FROM meta"))

    def claim(self, name: str, root_seed: int) -> None:
        """Mark the file as this campaign's; StoreError if it holds another one."""
        want = self.holds(name, root_seed)
        try:                      # the first write: a file that cannot take it is said now
            self.db.executemany("INSERT OR REPLACE INTO meta VALUES (?, ?)", want.items())
            self.db.commit()
        except sqlite3.Error as e:
            raise StoreError(f"{self.path}: cannot write the results file ({e})") from None

    def holds(self, name: str, root_seed: int) -> dict[str, str]:
        """StoreError if the file holds another campaign than ``name`` with ``root_seed``
        (its seeds would be other runs'); the meta that marks it this one's."""
        m = self.meta()
        want = {"name": name, "root_seed": str(root_seed)}
        for k, v in want.items():
            if k in m and m[k] != v:
                raise StoreError(f"{self.path} holds campaign {m.get('name')!r} with "
                                 f"root_seed {m.get('root_seed')}, not {name!r} with "
                                 f"root_seed {root_seed}: use another --db")
        return want

    # -- runs -------------------------------------------------------------------------------
    def done(self) -> set[str]:
        """The runs with a result (ok or crashed): a lost run is to be run again."""
        return {k for (k,) in self.db.execute("SELECT run_key FROM runs WHERE status != 'lost'")}

    def counts(self, keys: set[str] | None = None) -> dict[str, int]:
        """Stored runs by status: ``ok``, ``crashed`` (the model raised), ``lost`` (the cluster
        lost the task: no result); ``keys``: of those runs only (a campaign's own, when its
        grid shrank since)."""
        out = {"ok": 0, "crashed": 0, "lost": 0}
        for key, status in self.db.execute("SELECT run_key, status FROM runs"):
            if status not in STATUSES:
                raise StoreError(f"{self.path}: run {key}: a damaged row (status "
                                 f"{status!r})")
            if keys is None or key in keys:
                out[status] += 1
        return out

    def commits(self) -> set[tuple[str, int]]:
        return set(self.db.execute("SELECT DISTINCT commit_id, dirty FROM runs"))

    def add(self, rows: Iterable[dict[str, Any]], commit_id: str, dirty: bool) -> int:
        """Store rows (a run already stored is kept as it was, unless it was lost); returns
        how many were new."""
        rows = list(rows)
        now = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
        try:                      # one transaction: a chunk is stored whole or not at all
            self.db.executemany("DELETE FROM runs WHERE run_key = ? AND status = 'lost'",
                                [(r["run_key"],) for r in rows if r["status"] != "lost"])
            cur = self.db.executemany(
                f"INSERT OR IGNORE INTO runs ({', '.join(COLUMNS)}) "
                "VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                [(r["run_key"], r["point_key"], json.dumps(r["args"]), r["seed_index"],
                  r["seed"], r["status"], r["error"], json.dumps(r["metrics"]), r["wall_s"],
                  r["worker"], commit_id, int(dirty), now, r.get("code")) for r in rows])
            self.db.commit()
        except sqlite3.Error as e:
            try:
                self.db.rollback()
            except sqlite3.Error:
                pass
            raise StoreWriteError(f"{self.path}: cannot store results ({e}); the runs "
                                  f"stored before are kept, and campaign run goes on from "
                                  f"them") from None
        return cur.rowcount

    def rows(self) -> list[dict[str, Any]]:
        """Every stored run; a row that is not what ``add`` writes (a file edited or damaged
        by hand) is a StoreError naming it."""
        out = []
        try:
            select = ", ".join(c if c in self._columns else "NULL" for c in COLUMNS)
            cur = self.db.execute(f"SELECT {select} FROM runs ORDER BY point_key, seed_index")
            for values in cur:
                r = dict(zip(COLUMNS, values))
                try:
                    r["args"] = json.loads(r["args"])
                    r["metrics"] = json.loads(r["metrics"]) if r["metrics"] else None
                    point = json.loads(r["point_key"])
                except (TypeError, ValueError) as e:
                    raise StoreError(f"{self.path}: run {r['run_key']}: a damaged row "
                                     f"({e})") from None
                if not isinstance(r["args"], list) or not isinstance(point, dict) or \
                        r["status"] not in STATUSES or (r["status"] == "ok" and
                                                        not _sound_metrics(r["metrics"])):
                    raise StoreError(f"{self.path}: run {r['run_key']}: a damaged row (not "
                                     f"what a campaign run stores)")
                out.append(r)
        except sqlite3.DatabaseError as e:
            raise StoreError(f"{self.path}: not a campaign results file ({e})") from None
        return out

    # -- export -----------------------------------------------------------------------------
    def flat_rows(self) -> list[dict[str, Any]]:
        """One flat dict a run: the columns, each grid parameter and each metric."""
        out = []
        for r in self.rows():
            flat = {k: v for k, v in r.items() if k not in ("metrics", "args")}
            flat["args"] = " ".join(r["args"])
            flat.update({f"param_{k}": json.dumps(v) if isinstance(v, list) else v
                         for k, v in json.loads(r["point_key"]).items()})
            flat.update({f"m_{k}": json.dumps(v, sort_keys=True) if isinstance(v, dict) else v
                         for k, v in (r["metrics"] or {}).items()})   # a histogram: JSON text
            out.append(flat)
        return out

    def export_csv(self, path: str | Path) -> int:
        rows = self.flat_rows()
        fields = sorted({k for r in rows for k in r}, key=lambda k: (
            COLUMNS.index(k) if k in COLUMNS else len(COLUMNS), k))
        text = io.StringIO(newline="")
        w = csv.DictWriter(text, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
        _write_whole(path, text.getvalue().encode("utf-8"))
        return len(rows)

    def export_parquet(self, path: str | Path) -> int:
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            raise StoreError("Parquet needs pyarrow, which comes with the 'campaign' extra: "
                             "pip install 'rprs[campaign]'; --csv needs nothing more") from None
        rows = self.flat_rows()
        names = sorted({k for r in rows for k in r}, key=lambda k: (
            COLUMNS.index(k) if k in COLUMNS else len(COLUMNS), k))
        table = [{k: r.get(k) for k in names} for r in rows]
        for k in names:
            # a grid key with numbers and words (load = [1, "saturate"]), or flags and
            # numbers: a Parquet column has one type, so such a column is text, each value
            # as the CSV writes it (integers and floats together are floats)
            kinds = {type(r[k]) for r in table if r[k] is not None}
            if len(kinds) > 1 and not kinds <= {int, float}:
                for r in table:
                    if r[k] is not None:
                        r[k] = str(r[k])
        buf = io.BytesIO()      # not to ``path``: pyarrow removes a file it fails to write
        pq.write_table(pa.Table.from_pylist(table), buf)
        _write_whole(path, buf.getvalue())
        return len(rows)


def _write_whole(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all (``hil.sim.trace.OutputFile``); an
    OSError names ``path``."""
    from ..sim.trace import OutputFile
    try:
        out = OutputFile(str(path), binary=True)
        try:
            out.f.write(data)
        except BaseException:
            out.discard()
            raise
        out.commit()
    except OSError as exc:
        exc.filename = str(path)
        raise
