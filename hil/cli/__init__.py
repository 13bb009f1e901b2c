"""The ``rprs`` command line, one module per command (as cantools and python-can lay out
theirs): ``sim``, ``demo``, ``encode``/``decode`` (codec), ``child``/``submodules``/``father``
(robots), ``radio-hub`` (hub), ``inject``, ``bench``, ``conformance``, ``plot``, ``monitor``,
``soak``. Option
types and shared options live in ``common``; ``trace_digests`` holds seeded ``rprs sim`` runs
whose traces must not change by accident (tests/test_trace_digests.py).

A user mistake (bad option value, unreadable file, malformed input) prints one line starting
``rprs: error:`` and exits with status 2; it never shows a traceback.
"""
from __future__ import annotations

import argparse
import io
import sys
from typing import Sequence

from . import (bench, campaign, codec, conformance, demo, hub, inject, monitor, plot, robots, sim,
               soak, wireshark)
from .common import Parser, UserError

__all__ = ["build_parser", "main", "UserError"]

COMMANDS = (sim, demo, robots, plot, monitor, soak, campaign, hub, inject, bench, conformance,
            codec, wireshark)
"""Each adds its subcommands in this order (the order of ``rprs --help``)."""


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    from firmware_model.radio import PROTOCOL_VERSION
    try:
        mine = version("rprs")
    except PackageNotFoundError:          # run from a checkout that was never installed
        mine = "(not installed)"
    return f"rprs {mine}, radio protocol {PROTOCOL_VERSION}"


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="rprs", description="RPRS child firmware model, rotational TDMA radio "
               "MAC simulator and HIL bench")
    p.add_argument("--version", action="version", version=_version())
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for command in COMMANDS:
        command.add(sub)
    return p


def _stacks_on_sigusr1() -> None:
    """``kill -USR1 PID`` makes a running ``rprs`` print every thread's stack on stderr and go
    on: how to see where a bench process that has gone quiet is waiting."""
    import faulthandler
    import signal
    if hasattr(signal, "SIGUSR1"):
        try:
            faulthandler.register(signal.SIGUSR1, all_threads=True, chain=False)
        except (ValueError, OSError, RuntimeError, io.UnsupportedOperation):
            pass                     # no usable stderr (an embedding), or not the main thread


def main(argv: Sequence[str] | None = None) -> int:
    _stacks_on_sigusr1()
    parser = build_parser()
    try:
        a = parser.parse_args(argv)
        if not getattr(a, "command", None):
            parser.print_help()
            return 2
        return a.func(a)
    except UserError as exc:
        print(f"rprs: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("rprs: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0

