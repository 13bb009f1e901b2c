"""A campaign's statistics, per grid point, with confidence intervals (docs/campaigns.md).

* Proportions (messages failed, runs that broke an invariant): the Wilson score interval,
  95 %: ``(p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)``, z = 1.96. It stays
  inside [0, 1] and is sound for 0 or n successes, where the normal interval is not. Messages
  of one run are not independent (a dead robot fails several at once): the message rate is
  pooled over runs and its interval is narrower than the truth; the per-run rate is not.
* Percentiles (the longest re-formation of a run): the empirical quantile, and a 95 %
  percentile-bootstrap interval (resampling runs with replacement, 2000 times, a fixed seed).
* Every run that broke an invariant or crashed, as the ``rprs sim`` command that repeats it.
"""
from __future__ import annotations

import json
import math
from collections import defaultdict
from typing import Any

from .runs import broken

Z95 = 1.959963984540054


def wilson(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of ``k`` successes in ``n`` trials."""
    if n <= 0:
        return (0.0, 1.0)
    p = k / n
    d = 1 + z * z / n
    c = p + z * z / (2 * n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    lo = 0.0 if k == 0 else max(0.0, (c - h) / d)
    hi = 1.0 if k == n else min(1.0, (c + h) / d)
    return (lo, hi)


def bootstrap_quantile(values: list[float], q: float, n_boot: int = 2000,
                       seed: int = 0) -> tuple[float, float, float]:
    """(empirical ``q`` quantile, 95 % bootstrap low, high) of ``values``."""
    import numpy as np
    v = np.asarray(values, dtype=float)
    est = float(np.quantile(v, q))
    if len(v) < 2:
        return est, est, est
    rng = np.random.default_rng(seed)
    boots = np.quantile(v[rng.integers(0, len(v), size=(n_boot, len(v)))], q, axis=1)
    return est, float(np.quantile(boots, 0.025)), float(np.quantile(boots, 0.975))


def pooled_quantile(hists: list[dict[str, int]], q: float) -> float:
    """The ``q`` quantile (nearest rank) of the values counted in the histograms ``hists``
    (value as text -> count), pooled."""
    pooled: dict[float, int] = defaultdict(int)
    for h in hists:
        for text, n in h.items():
            pooled[float(text)] += n
    total = sum(pooled.values())
    rank, seen = min(total - 1, int(q * total)), 0
    for value in sorted(pooled):
        seen += pooled[value]
        if seen > rank:
            return value
    return math.nan


def bootstrap_pooled(hists: list[dict[str, int]], q: float, n_boot: int = 500,
                     seed: int = 0) -> tuple[float, float, float]:
    """(pooled ``q`` quantile, 95 % bootstrap low, high), resampling whole runs (a run's
    messages are not independent of each other)."""
    import random
    est = pooled_quantile(hists, q)
    if len(hists) < 2:
        return est, est, est
    rng = random.Random(seed)
    boots = sorted(pooled_quantile([rng.choice(hists) for _ in hists], q)
                   for _ in range(n_boot))
    return est, boots[int(0.025 * n_boot)], boots[min(n_boot - 1, int(0.975 * n_boot))]


def bootstrap_mean(values: list[float], n_boot: int = 2000,
                   seed: int = 0) -> tuple[float, float, float]:
    """(mean, 95 % percentile-bootstrap low, high) of ``values``."""
    import random
    est = sum(values) / len(values)
    if len(values) < 2:
        return est, est, est
    rng = random.Random(seed)
    boots = sorted(sum(rng.choice(values) for _ in values) / len(values)
                   for _ in range(n_boot))
    return est, boots[int(0.025 * n_boot)], boots[min(n_boot - 1, int(0.975 * n_boot))]


def command(row: dict[str, Any]) -> str:
    """The one-line ``rprs sim`` command that repeats a run exactly."""
    import shlex
    return "rprs sim " + " ".join(shlex.quote(a) for a in row["args"]) + f" --seed {row['seed']}"


def _failing(row: dict[str, Any]) -> dict[str, Any]:
    """A failing run for the report: its command, what it broke, and for a crashed run the
    last line of what it raised (a crash in the campaign's own metrics hook is not in what
    the command repeats: ``rprs sim`` runs no hook)."""
    out: dict[str, Any] = {"command": command(row), "broke": _broke(row)}
    if row["status"] == "crashed":
        lines = [x for x in (row.get("error") or "").splitlines() if x.strip()]
        out["error"] = lines[-1].strip() if lines else None
    return out


def _broke(row: dict[str, Any]) -> list[str]:
    return broken(row["metrics"] if row["status"] == "ok" else None, row["args"])


REFORM_QUANTILES = (0.5, 0.99, 0.999)
"""The quantiles of a run's longest re-formation the report gives."""
LATENCY_QUANTILES = (0.5, 0.95, 0.99)
"""The quantiles of message latency the report gives."""


def quantile_name(q: float) -> str:
    """``p50``, ``p95``, ``p99.9``: a quantile as the report's keys name it."""
    return f"p{q * 100:g}"


def runs_for(q: float) -> int:
    """The fewest runs a ``q`` quantile is reported from: 1 / (1 - q) (2 for the median, 100
    for p99, 1000 for p99.9). With fewer, the quantile is the sample's largest value and a
    bootstrap of it is no interval: the report says how many runs it needs instead."""
    return math.ceil(round(1 / (1 - q), 6))


def summarize(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per grid point: counts, rates with Wilson intervals, re-formation quantiles with
    bootstrap intervals, and the failing runs' commands."""
    by_point: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        if r["status"] != "lost":        # the cluster lost it: no result (store.py)
            by_point[r["point_key"]].append(r)
    out = []
    for key in sorted(by_point):
        runs = by_point[key]
        ok = [r for r in runs if r["status"] == "ok"]
        sub = sum(r["metrics"]["submitted"] for r in ok)
        fail = sum(r["metrics"]["failed"] for r in ok)
        bad = [r for r in runs if _broke(r)]
        reform = [r["metrics"]["reform_max_s"] for r in ok
                  if r["metrics"]["reform_max_s"] is not None]
        point = {
            "point": json.loads(key), "runs": len(runs), "crashed": len(runs) - len(ok),
            "messages": sub, "failed": fail,
            "failed_rate": fail / sub if sub else None, "failed_ci95": wilson(fail, sub),
            "runs_broken": len(bad), "runs_broken_rate": len(bad) / len(runs),
            "runs_broken_ci95": wilson(len(bad), len(runs)),
            "reform_runs": len(reform),
            "corrupted_acted_on": sum(r["metrics"]["corrupted_acted_on"] for r in ok),
            "failing": [_failing(r) for r in bad],
        }
        point["duplicates"] = sum(r["metrics"]["duplicates"] for r in ok)
        # message latency, pooled over the point's runs, each quantile only from enough
        # messages; delivered throughput, the runs' mean with its bootstrap interval
        hists = [r["metrics"]["latency_ms"] for r in ok if r["metrics"].get("latency_ms")]
        lat_n = sum(sum(h.values()) for h in hists)
        point["latency_messages"] = lat_n
        for q in LATENCY_QUANTILES:
            name = quantile_name(q)
            if hists and lat_n >= runs_for(q):
                est, lo, hi = bootstrap_pooled(hists, q)
                point[f"latency_{name}_ms"] = [est, lo, hi]
            elif hists:
                point[f"latency_{name}_ms"] = None
        custom: dict[str, list[float]] = defaultdict(list)
        for r in ok:
            for name, v in (r["metrics"].get("custom") or {}).items():
                custom[name].append(v)
        if custom:          # the campaign's own metrics: each a mean with its interval
            point["custom"] = {name: [round(x, 6) for x in bootstrap_mean(vs)] + [len(vs)]
                               for name, vs in sorted(custom.items())}
        tput = [r["metrics"]["throughput"] for r in ok if "throughput" in r["metrics"]]
        if tput:
            est, lo, hi = bootstrap_mean(tput)
            point["throughput"] = [round(est, 4), round(lo, 4), round(hi, 4)]
        for q in REFORM_QUANTILES:
            name = quantile_name(q)
            if reform and len(reform) >= runs_for(q):
                est, lo, hi = bootstrap_quantile(reform, q)
                point[f"reform_{name}_s"] = [round(est, 3), round(lo, 3), round(hi, 3)]
            elif reform:
                point[f"reform_{name}_s"] = None          # too few runs: no estimate
        out.append(point)
    return out


def fixed_and_varying(points: list[dict[str, Any]]) -> tuple[dict[str, Any], list[str]]:
    """The grid keys that have one value at every point (with it) and the sorted keys whose
    values differ between points: the report names the first once and tabulates the second."""
    keys = sorted({k for p in points for k in p["point"]})
    fixed: dict[str, Any] = {}
    varying = []
    for k in keys:
        values = {json.dumps(p["point"].get(k), sort_keys=True) for p in points}
        if len(values) == 1 and all(k in p["point"] for p in points):
            fixed[k] = points[0]["point"][k]
        else:
            varying.append(k)
    return fixed, varying


def point_label(point: dict[str, Any]) -> str:
    """A grid point (or the rest of one) as a legend label: ``checksum=true load=1
    robots=1,2``, every key, sorted, values as the campaign file writes them."""
    return " ".join(f"{k}={v if isinstance(v, str) else json.dumps(v)}"
                    for k, v in sorted(point.items())) or "(one point)"


def ber_series(points: list[dict[str, Any]],
               fixed: Any = ()) -> dict[str, list[tuple[float, ...]]]:
    """The lines of the failure-vs-BER plot: {label: [(ber, rate, ci low, ci high), ...]
    sorted by ber}, one line per rest-of-point (every grid key but ``ber``), so points that
    differ in any other key (robots, load, checksum, ...) are never drawn as one line. Keys in
    ``fixed`` (one value at every point: the plot's title names them) stay out of the
    labels."""
    series: dict[str, list] = defaultdict(list)
    for p in points:
        if p["failed_rate"] is not None:
            rest = {k: v for k, v in p["point"].items() if k != "ber" and k not in fixed}
            series[point_label(rest)].append(
                (p["point"].get("ber", 0.0), p["failed_rate"], *p["failed_ci95"]))
    return {label: sorted(pts) for label, pts in sorted(series.items())}


def plot(points: list[dict[str, Any]], rows: list[dict[str, Any]], directory) -> list[str]:
    """failure rate against BER, one line per rest-of-point (when the grid varies ``ber``),
    and the CDF of each point's longest re-formation; PNG files written into ``directory``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from pathlib import Path
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    written = []
    fixed, varying = fixed_and_varying(points)
    title = f"every point: {point_label(fixed)}" if fixed else None
    bers = {p["point"].get("ber", 0.0) for p in points}
    if len(bers) > 1:
        fig, ax = plt.subplots(figsize=(6, 4))
        if title:
            ax.set_title(title, fontsize=8)
        for label, pts in ber_series(points, fixed).items():
            x = [a[0] for a in pts]
            y = [a[1] for a in pts]
            err = [[max(0.0, a[1] - a[2]) for a in pts], [max(0.0, a[3] - a[1]) for a in pts]]
            ax.errorbar(x, y, yerr=err, marker="o", capsize=3, label=label)
        ax.set_xlabel("byte error rate")
        # BERs are small: in plain decimals their ticks (0.000250, ...) ran into each other
        ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(nbins=5))
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3), useMathText=True)
        ax.set_ylabel("messages failed (Wilson 95 %)")
        ax.legend(title="grid point but ber", fontsize=6)
        f = d / "failure_vs_ber.png"
        fig.tight_layout()
        fig.savefig(f, dpi=100)
        plt.close(fig)
        written.append(str(f))
    fig, ax = plt.subplots(figsize=(6, 4))
    any_line = False
    by_point: dict[str, list[float]] = defaultdict(list)
    for r in rows:
        if r["status"] == "ok" and r["metrics"]["reform_max_s"] is not None:
            by_point[r["point_key"]].append(r["metrics"]["reform_max_s"])
    for key, vals in sorted(by_point.items()):
        vals.sort()
        point = json.loads(key)
        ax.step(vals, [(i + 1) / len(vals) for i in range(len(vals))], where="post",
                label=point_label({k: point.get(k) for k in varying}) if varying
                else "the point")
        any_line = True
    if any_line:
        if title:
            ax.set_title(title, fontsize=8)
        ax.set_xlabel("longest ring re-formation of a run (s)")
        ax.set_ylabel("share of runs")
        ax.legend(fontsize=6)
        f = d / "reformation_cdf.png"
        fig.tight_layout()
        fig.savefig(f, dpi=100)
        written.append(str(f))
    plt.close(fig)
    return written
