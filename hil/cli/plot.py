"""``rprs plot``: the paper's Fig. 7 timeline from a trace (hil.view.plot)."""
from __future__ import annotations

import argparse
import sys

from .common import UserError

def cmd_plot(a: argparse.Namespace) -> int:
    from ..view.plot import PlotError, plot_trace
    from ..sim.trace import TraceError, read_trace
    try:
        info = plot_trace(read_trace(a.trace), a.output, a.start, a.end)
    except (TraceError, PlotError) as exc:
        raise UserError(str(exc)) from None
    print(f"wrote {a.output}: {info['turns']} turns from {info['window_s'][0]:.3f} s to "
          f"{info['window_s'][1]:.3f} s; in the whole trace {info['misses']} missed, "
          f"{info['collided']} collided", file=sys.stderr)
    return 0


def add(sub) -> None:
    pl = sub.add_parser("plot", help="draw the paper's Fig. 7 timeline from a trace")
    pl.add_argument("trace", metavar="TRACE", help="a JSON Lines trace (rprs sim --trace), "
                    "plain or gzipped")
    pl.add_argument("-o", "--output", required=True, metavar="FILE.png|svg|pdf",
                    help="the figure to write (.png, .svg or .pdf)")
    pl.add_argument("--start", type=float, metavar="S", help="window start (s)")
    pl.add_argument("--end", type=float, metavar="S", help="window end (s)")
    pl.set_defaults(func=cmd_plot)
