"""``rprs conformance``: check one robot against docs/protocol.md, clause by clause
(hil.bench.conformance)."""
from __future__ import annotations

import argparse
import sys

from .common import (UserError, auth_option, file_name, digit, output_file, port_name, positive,
                     robot_list, stdout_console, txen_option)


VERDICT_STYLE = {"pass": "[green]pass[/green]", "FAIL": "[red]FAIL[/red]", "n/a": "[dim]n/a[/dim]"}
"""How the table shows each verdict (hil.bench.conformance.Check.verdict)."""


def cmd_conformance(a: argparse.Namespace) -> int:
    from ..bench.conformance import ConformanceError, Tester
    from ..bench.serial_radio import PortError
    from firmware_model.radio.auth import FreshnessExhausted
    if a.tester is not None and a.tester == a.id:
        raise UserError(f"--tester must differ from --id (both {a.id})")
    me = a.tester if a.tester is not None else (0 if a.id != 0 else 1)
    if a.team and not {a.id, me} <= set(a.team):
        raise UserError(f"--team {','.join(map(str, a.team))} must hold the robot's ID {a.id} "
                        f"and this PC's {me}: the robot's team holds both")
    if a.junit:
        output_file(a.junit, "JUnit XML")
    quiet = a.quiet
    try:
        t = Tester(a.radio, a.id, a.profile, a.tester, a.tolerance_ms, a.turns,
                   progress=None if quiet else lambda s: print(s, file=sys.stderr, flush=True),
                   key=a.auth_key, team=tuple(a.team) if a.team else tuple(range(7)),
                   checksum=a.checksum, wrap=a.wrap, txen=a.txen)
    except (PortError, ValueError, FreshnessExhausted) as exc:
        raise UserError(str(exc)) from None
    try:
        rep = t.run()
        error = None
    except ConformanceError as exc:
        rep, error = t.report, str(exc)
    except OSError as exc:
        rep, error = t.report, f"the port failed: {exc}"
    except FreshnessExhausted as exc:
        rep, error = t.report, str(exc)
    rep.stopped = error
    from rich import box
    from rich.table import Table
    table = Table(box=box.SIMPLE_HEAD, title=f"robot {a.id} against docs/protocol.md "
                  f"(profile {a.profile})")
    for col in ("clause", "check", "verdict", "measured"):
        table.add_column(col)
    for c in rep.checks:
        table.add_row(c.clause, c.name, VERDICT_STYLE[c.verdict], c.figure)
    stdout_console().print(table)
    for note in rep.notes:
        print(f"rprs conformance: {note}")
    if error:
        print(f"rprs conformance: stopped: {error}")
    if a.junit:
        try:
            with open(a.junit, "wb") as fh:
                fh.write(rep.junit())
        except OSError as exc:
            raise UserError(f"cannot write JUnit XML {a.junit}: {exc.strerror}") from None
    return 0 if rep.passed and not error else 1


def add(sub) -> None:
    p = sub.add_parser("conformance", help="check a robot against docs/protocol.md, clause by "
                       "clause, from a PC in a ring of two with it")
    p.add_argument("--radio", type=port_name, required=True, metavar="PORT",
                   help="the serial port of this PC's radio (or a radio-hub pty)")
    p.add_argument("--id", type=digit(0, 6, "robot ID"), required=True,
                   help="the ID of the robot under test")
    txen_option(p)
    p.add_argument("--profile", choices=("rprs", "paper"), default="rprs",
                   help="the profile the robot runs (docs/protocol.md; §9.1 for paper)")
    p.add_argument("--tester", type=digit(0, 6, "tester ID"), default=None,
                   help="this PC's robot ID in the ring (default 0, or 1 when testing 0); "
                   "the robot's team must hold it")
    p.add_argument("--tolerance-ms", type=positive, default=15.0, metavar="MS",
                   help="timing tolerance for a PC and its port (default 15)")
    p.add_argument("--team", type=robot_list, metavar="IDS",
                   help="the robot's team (default 0-6), as given to it: in the paper profile "
                   "its static ring, whose absent robots keep their turns until dropped")
    p.add_argument("--turns", type=digit(3, 1000, "turns"), default=20,
                   help="hand-overs timed (default 20)")
    auth_option(p)
    p.add_argument("--checksum", action="store_true",
                   help="the robot runs the checksum extension (rprs child --checksum, "
                   "docs/protocol.md clause 20): every frame ends with crc(NNNNN), ours too, "
                   "and one with a wrong checksum must not be acted on")
    p.add_argument("--wrap", action="store_true",
                   help="also run the robot's own message Number past '99' (clause 45): "
                   "about a hundred status() orders, about 10 s more on the air")
    p.add_argument("--junit", type=file_name, metavar="FILE",
                   help="write the verdicts as JUnit XML here")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=cmd_conformance)
