"""One run of a campaign: a grid point's ``rprs sim`` arguments and a seed in, one row out.

This is what the Dask workers execute (``run_chunk``). A run that raises is recorded as
``crashed`` with its traceback, never dropped. The metrics are the soak's invariants
(hil/sim/soak.py) and the delivery accounting of ``World.summary``.
"""
from __future__ import annotations

import argparse
import os
import socket
import time
import traceback
from typing import Any, Callable, NoReturn, Sequence

from .code import code_identity
from ..sim.soak import run_timing_reformations
from ..sim.config import SimConfig
from ..sim.world import World

Item = tuple[str, str, tuple[str, ...], int, int]
"""(run key, point key, rprs sim arguments, seed index, seed)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise ValueError(message)


def sim_config_for(args: Sequence[str], seed: int) -> SimConfig:
    """The SimConfig ``rprs sim ARGS --seed SEED`` runs; ValueError for what it refuses: the
    options it cannot parse (the parser is ``rprs sim``'s) and the settings that cannot work
    (``SimConfig.validate``'s ConfigError, as ``rprs sim`` checks them before it runs)."""
    from ..cli.common import UserError
    from ..cli.sim import add_sim_options, sim_config
    p = _Parser(prog="rprs sim", add_help=False)
    add_sim_options(p)
    a = p.parse_args([*args, "--seed", str(seed)])
    try:
        cfg = sim_config(a)
    except UserError as e:
        raise ValueError(str(e)) from None
    cfg.validate()
    return cfg


def check_args(args: Sequence[str]) -> SimConfig:
    """ValueError if ``rprs sim ARGS`` would refuse them; else the settings they make (seed
    0), by which two grid points spelled apart are told to be one (campaign/spec.py)."""
    return sim_config_for(args, 0)


class MetricsHookError(ValueError):
    """A ``metrics`` hook that cannot be used; the message says why."""


def metrics_hook(spec: str) -> Callable[[list, Any], dict]:
    """The function a campaign file's ``metrics = "module:function"`` names, imported (on
    the worker as in the client: the module must be importable on both)."""
    import importlib
    mod_name, sep, fn_name = spec.partition(":")
    if not sep or not mod_name or not fn_name.isidentifier() or mod_name.startswith("."):
        raise MetricsHookError(f"{spec!r}: give 'module:function' (an absolute module name)")
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as e:
        raise MetricsHookError(f"{spec!r}: cannot import {mod_name}: {e} (a module beside "
                               f"the campaign file is found; else put its directory on "
                               f"PYTHONPATH)") from None
    except Exception as e:      # noqa: BLE001 - the user's module failed: said in one line
        raise MetricsHookError(f"{spec!r}: importing {mod_name} failed: "
                               f"{type(e).__name__}: {e}") from None
    fn = getattr(mod, fn_name, None)
    if not callable(fn):
        raise MetricsHookError(f"{spec!r}: {mod_name} has no function {fn_name}")
    return fn


def custom_metrics(hook: str, events: list, world: Any) -> dict[str, float]:
    """A run's own metrics: ``hook``'s function called with the run's typed trace events
    (hil/sim/events.py, in order) and its finished world; it returns {name: number}. A value
    that is no number (or a name that is no string) makes the run crash, with that reason."""
    out = metrics_hook(hook)(events, world)
    if not isinstance(out, dict) or not all(
            isinstance(k, str) and isinstance(v, (int, float)) and not isinstance(v, bool)
            for k, v in out.items()):
        raise MetricsHookError(f"{hook} must return {{name: number}}, got {out!r:.200}")
    return {k: float(v) for k, v in out.items()}


def metrics_of(cfg: SimConfig, hook: str | None = None) -> dict[str, Any]:
    """Run the world of ``cfg`` to its end; the campaign's metrics (``hook``: the campaign's
    own, ``custom_metrics``, under ``custom``)."""
    events: list = []
    w = World(cfg, listeners=[events.append] if hook else ())
    reform, not_reformed = run_timing_reformations(w, cfg.faults)
    s = w.summary()
    extra = {"custom": custom_metrics(hook, events, w)} if hook else {}
    return {**extra,
        "submitted": s["submitted"], "delivered": s["delivered"], "failed": s["failed"],
        "pending": s["pending"], "duplicates": s["duplicate_deliveries"],
        "misdelivered": s["wrong_robot_deliveries"],
        "corrupted_acted_on": s["corrupt_deliveries"], "collisions": s["collisions"],
        "membership_changes": len(s["membership_changes"]),
        "reformations": len(reform), "reform_max_s": max(reform) if reform else None,
        "not_reformed": not_reformed,
        # delivered messages by latency (ms, submission to the last acknowledgement): pooled
        # over a point's runs by the report; and delivered messages a simulated second
        "latency_ms": {str(ms): n for ms, n in sorted(w.ledger.latency_ms.items())},
        "throughput": s["delivered"] / cfg.duration if cfg.duration else 0.0,
    }


def broken(m: dict[str, Any] | None, args: Sequence[str] = ()) -> list[str]:
    """The invariants a run's metrics break, as docs/guarantees.md defines them: nothing to
    the wrong robot and a ring that re-forms, always; nothing delivered twice and no
    corrupted command acted on, only with the checksum extension (``--checksum`` in
    ``args``): without it those counts are what the paper's frame lets through, reported,
    not broken promises."""
    if m is None:
        return ["crashed"]
    out = []
    if m["duplicates"] and "--checksum" in args:
        out.append("delivered twice")
    if m["misdelivered"]:
        out.append("delivered to the wrong robot")
    if m["corrupted_acted_on"] and "--checksum" in args:
        out.append("acted on a corrupted command")
    if m["not_reformed"]:
        out.append("ring did not re-form")
    return out


def run_one(item: Item, measure: Callable[[SimConfig], dict] = metrics_of) -> dict[str, Any]:
    """One run as a database row (``status`` ok or crashed, with the traceback)."""
    key, point_key, args, index, seed = item
    t0 = time.perf_counter()
    row: dict[str, Any] = {"run_key": key, "point_key": point_key, "args": list(args),
                           "seed_index": index, "seed": seed,
                           "worker": f"{socket.gethostname()}:{os.getpid()}",
                           "code": code_identity()}
    try:
        row.update(status="ok", error=None, metrics=measure(sim_config_for(args, seed)))
    except Exception:   # noqa: BLE001 - a crashed run is a result, recorded with its cause
        row.update(status="crashed", error=traceback.format_exc(), metrics=None)
    row["wall_s"] = time.perf_counter() - t0
    return row


def run_chunk(items: list[Item], measure: Callable[[SimConfig], dict] = metrics_of) -> list[dict]:
    """Several runs in one task (fewer tasks: less scheduling overhead)."""
    return [run_one(it, measure) for it in items]
