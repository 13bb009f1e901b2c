"""A campaign's specification: a TOML file naming a grid of ``rprs sim`` parameters and the
seeds per point (docs/campaigns.md).

    [campaign]
    name = "ber-vs-ring"
    seeds = 20                  # runs per grid point
    root_seed = 2026            # every run's seed derives from it (seeds.py)
    duration = 60               # simulated seconds, unless the grid says otherwise

    [grid]                      # every combination of these is one point
    robots = ["0,1,2", "0,1,2,3,4"]
    ber = [0.0, 0.001]
    checksum = [false, true]
    fault = [[], ["fail:2@10", "recover:2@20"]]

Grid keys are ``rprs sim`` options without the dashes (``father_standby`` for
``--father-standby``): a boolean is a flag, ``fault`` (and ``fail``, ``recover``, ``power``)
a list of values for the repeatable option, anything else one value. Each point is checked
with ``rprs sim``'s own option parser and ``SimConfig.validate`` before anything runs, so a bad
value is one clear error.
Outputs (``trace``, ``vcd``, ``pcap``, ``json``) and ``seed`` are the campaign's, not the
grid's.
"""
from __future__ import annotations

import itertools
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10
    import tomli as tomllib

REPEATABLE = ("fault", "fail", "recover", "power")
NOT_IN_GRID = ("seed", "trace", "vcd", "pcap", "json", "no_progress", "cpu_report")


class SpecError(ValueError):
    """A campaign file that cannot be run; the message says where and why."""


@dataclass(frozen=True)
class Point:
    """One grid point: its parameters and the ``rprs sim`` arguments they make."""

    params: tuple[tuple[str, Any], ...]
    args: tuple[str, ...]

    @property
    def key(self) -> str:
        """Canonical text of the parameters: the point's identity in the database."""
        return json.dumps(dict(self.params), sort_keys=True, separators=(",", ":"))


@dataclass(frozen=True)
class Spec:
    name: str
    seeds: int
    root_seed: int
    points: tuple[Point, ...]
    chunk: int
    metrics: str | None = None
    """``module:function`` computing a run's own metrics from its trace events and world
    (``hil.campaign.runs.custom_metrics``), or None."""

    @property
    def runs(self) -> int:
        return self.seeds * len(self.points)


def _args(params: dict[str, Any]) -> tuple[str, ...]:
    out: list[str] = []
    for k in sorted(params):
        v = params[k]
        opt = "--" + k.replace("_", "-")
        if isinstance(v, bool):
            if v:
                out.append(opt)
        elif k in REPEATABLE:
            for item in v:
                out += [opt, str(item)]
        else:
            out += [opt, str(v)]
    return tuple(out)


def points_of(grid: dict[str, list[Any]], base: dict[str, Any]) -> tuple[Point, ...]:
    keys = sorted(grid)
    out = []
    for combo in itertools.product(*(grid[k] for k in keys)):
        params = dict(base)
        params.update(zip(keys, combo))
        out.append(Point(tuple(sorted(params.items(), key=lambda kv: kv[0])), _args(params)))
    return tuple(out)


MAX_RUNS = 1_000_000
"""The most runs a campaign file may plan (about 23 core-days at two seconds a run)."""


def importable_beside(path: str | Path) -> None:
    """Let a ``metrics`` hook's module sit beside its campaign file: that file's directory
    goes first on this process's import path and on ``PYTHONPATH``, which the embedded
    cluster's worker processes start with (an external cluster's workers need it on their
    own path: docs/campaigns.md)."""
    import os
    where = str(Path(path).resolve().parent)
    if where not in sys.path:
        sys.path.insert(0, where)
    paths = os.environ.get("PYTHONPATH", "").split(os.pathsep)
    if where not in paths:
        os.environ["PYTHONPATH"] = os.pathsep.join([where] + [p for p in paths if p])


def load_spec(path: str | Path, check=None) -> Spec:
    """Read and check a campaign file. ``check(args)`` raises ValueError for arguments
    ``rprs sim`` refuses (the CLI passes its parser), else gives the settings they make (or
    None), which two points must not share."""
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as e:
        raise SpecError(f"cannot read campaign file {path}: {e.strerror}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise SpecError(f"{path}: not TOML: {e}") from None
    if not data:
        # (an empty file, or comments only: most likely the wrong file, not 10 default runs)
        raise SpecError(f"{path}: no [campaign] or [grid] table: nothing says what to run "
                        "(docs/campaigns.md)")
    unknown = set(data) - {"campaign", "grid"}
    if unknown:
        raise SpecError(f"{path}: unknown table(s) {', '.join(sorted(unknown))}; "
                        "use [campaign] and [grid]")
    camp = data.get("campaign", {})
    grid = data.get("grid", {})
    if not isinstance(camp, dict) or not isinstance(grid, dict):
        raise SpecError(f"{path}: [campaign] and [grid] must be tables")
    extra = set(camp) - {"name", "seeds", "root_seed", "duration", "chunk", "metrics"}
    if extra:
        raise SpecError(f"{path}: unknown [campaign] key(s) {', '.join(sorted(extra))}")
    name = camp.get("name", Path(path).stem)
    seeds = camp.get("seeds", 10)
    root = camp.get("root_seed", 0)
    chunk = camp.get("chunk", 0)
    for what, v, lo in (("seeds", seeds, 1), ("root_seed", root, 0), ("chunk", chunk, 0)):
        if not isinstance(v, int) or isinstance(v, bool) or v < lo:
            raise SpecError(f"{path}: [campaign] {what} must be an integer >= {lo}, got {v!r}")
    if not isinstance(name, str) or not name:
        raise SpecError(f"{path}: [campaign] name must be a non-empty string")
    base: dict[str, Any] = {}
    if "duration" in camp:
        base["duration"] = camp["duration"]
    for k, v in grid.items():
        if k in NOT_IN_GRID:
            raise SpecError(f"{path}: [grid] {k}: the campaign sets it (seeds derive from "
                            "root_seed; outputs are the database)")
        if not isinstance(v, list) or not v:
            raise SpecError(f"{path}: [grid] {k} must be a non-empty list of values")
        if k in REPEATABLE and not all(isinstance(x, list) for x in v):
            raise SpecError(f"{path}: [grid] {k}: each value is a list of {k} specs, e.g. "
                            f"{k} = [[], [\"...\"]]")
    metrics = camp.get("metrics")
    if metrics is not None:
        from .runs import MetricsHookError, metrics_hook
        if not isinstance(metrics, str):
            raise SpecError(f"{path}: [campaign] metrics must be a string 'module:function'")
        importable_beside(path)
        try:
            metrics_hook(metrics)
        except MetricsHookError as e:
            raise SpecError(f"{path}: [campaign] metrics: {e}") from None
    planned = seeds * math.prod(len(v) for v in grid.values())
    if planned > MAX_RUNS:
        # (planned whole before the first run: ten times this took minutes and GBs, silent)
        raise SpecError(f"{path}: {planned:,} runs (seeds x grid points), more than "
                        f"{MAX_RUNS:,}: split it into several campaign files")
    points = points_of(grid, base)
    seen: set = set()
    for p in points:
        if p.key in seen:      # a value given twice: the same runs planned twice, one kept
            raise SpecError(f"{path}: [grid] gives the point {p.key} twice (a value repeated "
                            f"in a list): each point once")
        seen.add(p.key)
    if check is not None:
        made: dict[str, str] = {}
        for p in points:
            try:
                cfg = check(p.args)
            except ValueError as e:
                raise SpecError(f"{path}: grid point {p.key}: {e}") from None
            if cfg is None:
                continue
            # values spelled apart that make the same run: 1 and 1.0, "0,1" and "00,1"
            first = made.setdefault(repr(cfg), p.key)
            if first != p.key:
                raise SpecError(f"{path}: [grid] gives the points {first} and {p.key}, which "
                                f"make the same run (a value repeated in another spelling): "
                                f"each point once")
    return Spec(name, seeds, root, points, chunk, metrics)
