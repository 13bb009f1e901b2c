"""``rprs sim --cpu-report``: each child's CPU budget from the MB90F549 CPU model.

Per handler: how often it ran (calls a second), what one call costs (machine cycles: entry,
body and RETI), its share of the CPU, its latency (request to acceptance) and response (request
to its effects) in microseconds: median, 99th percentile and the worst seen. "worst case" adds
to an interrupt handler's worst response seen what the model does not simulate: the
instruction under way when the request comes (at most ``sample_wait_max`` cycles) and the
waits its rows' listings count in their worst case (each instruction fetched across a word
boundary, each CAN buffer access waiting; summed over the handler's rows, a bound where one
call runs one of them). For UART0 reception it is set against the deadline, one byte time (a
later read loses the next byte: ORE).
"""
from __future__ import annotations

from firmware_model.cycle_costs import DEFAULT_COSTS, CycleCosts
from firmware_model.interrupts import COSTED_BY, VECTORS, icr_of
from firmware_model.mcu.cpu import MAIN_LEVEL, Cpu
from firmware_model.timing import TICK_HZ

US = 1_000_000 / TICK_HZ


def _pct(counts, q: float) -> int:
    """The ``q`` quantile (nearest rank) of values counted in a Counter (ticks)."""
    total = sum(counts.values())
    if not total:
        return 0
    rank = min(total - 1, int(q * total))
    seen = 0
    for value in sorted(counts):
        seen += counts[value]
        if seen > rank:
            return value
    return value


def _source_kind(source: str) -> str:
    """A cost's source in a word or two: ``manual``, ``listing``, ``estimate``, or the file
    that changed it (``big.toml (was 95)``), its brackets whole."""
    head = source.split(":")[0]
    return head + ")" * (head.count("(") - head.count(")"))


def costed_by(name: str, costs: CycleCosts = DEFAULT_COSTS) -> dict:
    """Where handler ``name``'s cycles come from: its vector and ICR (none for main-loop
    work) and its rows of the cycle-cost table, each with its cycles and its source's kind
    (``manual``, ``listing``, ``estimate``, or the file that changed it)."""
    v = VECTORS.get(name)
    return {"vector": v.number if v else None, "icr": icr_of(v.number) if v else None,
            "costs": {row: {"cycles": getattr(costs, row).cycles,
                            "source": _source_kind(getattr(costs, row).source)}
                      for row in COSTED_BY.get(name, ())}}


def cpu_budget(cpu: Cpu, sample_wait: int, byte_ticks: int, span: int,
               costs: CycleCosts = DEFAULT_COSTS) -> dict:
    """The report of one CPU as plain data (JSON-ready): ``span`` ticks of simulated time."""
    cpu.settle()
    rows = []
    # a handler still running at the end (one longer than the run): its cycles so far count,
    # and its response is at least as long as it has run
    going: dict[str, tuple[int, int]] = {}
    for st, done, since in cpu.unfinished(cpu.sched.now):
        c, w = going.get(st.name, (0, 0))
        going[st.name] = (c + done, max(w, since))
    for s in sorted(cpu.stats.values(), key=lambda s: (s.level, s.name)):
        lat, resp = s.latency, s.response
        busy, still = s.busy + going.get(s.name, (0, 0))[0], going.get(s.name, (0, 0))[1]
        worst = max(s.worst_response, still)
        if s.level < MAIN_LEVEL:
            worst += sample_wait + sum(getattr(costs, row).worst_extra
                                       for row in COSTED_BY.get(s.name, ()))
        rows.append({
            "handler": s.name, "level": s.level, "calls": s.calls,
            "per_second": round(s.calls * TICK_HZ / span, 1) if span else 0.0,
            "cycles_per_call": round(s.busy / s.calls) if s.calls else 0,
            "load": round(busy / span, 6) if span else 0.0,
            **({"running_us": round(still * US, 1)} if s.name in going else {}),
            "latency_us": [round(_pct(lat, 0.5) * US, 1), round(_pct(lat, 0.99) * US, 1),
                           round(s.worst_latency * US, 1)],
            "response_us": [round(_pct(resp, 0.5) * US, 1), round(_pct(resp, 0.99) * US, 1),
                            round(max(s.worst_response, still) * US, 1)],
            "worst_case_us": round(worst * US, 1),
            **({"deadline_us": round(byte_ticks * US, 1)} if s.name.startswith("UART0 RX")
               else {}),
            **costed_by(s.name, costs),
        })
    return {"load": round((cpu.busy + cpu.running(cpu.sched.now)) / span, 6) if span else 0.0,
            "handlers": rows}


def print_cpu_report(world, costs, console=None) -> dict:
    """Print every child's budget (rich tables) on ``console`` (a rich Console class; rich's
    own by default); returns the same as data."""
    from rich import box
    from rich.console import Console
    from rich.table import Table
    make = console or Console
    con = make(width=max(make().width, 100))    # the table's width; wraps on narrower
    span = world.sched.now
    out = {}
    for r, cpu in sorted(world.cpus.items()):
        rep = cpu_budget(cpu, costs.sample_wait_max.cycles, world.byte_ticks[r], span, costs)
        out[r] = rep
        uart = world.stations[r].uart
        con.print(f"[bold]R{r} CPU budget[/bold] (MB90F549 at 16 MHz, cycle costs: "
                  f"firmware_model/cycle_costs.py): load {rep['load'] * 100:.2f} %, "
                  f"UART overruns {uart.overruns}, gaps in frames sent {uart.gaps} "
                  f"({uart.gap_ticks / 16:g} us)")
        deadline = None
        t = Table(box=box.SIMPLE_HEAD, show_edge=False, padding=(0, 1),
                  collapse_padding=True)
        for col in ("handler", "vec", "lvl", "calls/s", "cycles", "load %", "latency us",
                    "response us", "worst us"):
            t.add_column(col, justify="left" if col == "handler" else "right", no_wrap=True)
        for h in rep["handlers"]:
            worst = f"{h['worst_case_us']:g}"
            if "deadline_us" in h:
                deadline = (h["handler"], h["worst_case_us"], h["deadline_us"])
            t.add_row(h["handler"], "-" if h["vector"] is None else str(h["vector"]),
                      "-" if h["level"] == MAIN_LEVEL else str(h["level"]),
                      f"{h['per_second']:g}", str(h["cycles_per_call"]),
                      f"{h['load'] * 100:.2f}", "/".join(f"{v:g}" for v in h["latency_us"]),
                      "/".join(f"{v:g}" for v in h["response_us"]), worst)
        con.print(t)
        if deadline is not None:
            con.print(f"{deadline[0]} worst case {deadline[1]:g} us against its deadline, "
                      f"one byte: {deadline[2]:g} us"
                      + (": missed" if deadline[1] > deadline[2] else ""))
        for h in rep["handlers"]:
            if "running_us" in h:
                con.print(f"{h['handler']} still running at the end, {h['running_us']:g} us "
                          f"after its request")
    con.print("cycles: entry + body + RETI of one call; latency: request to acceptance; "
              "response: request to the handler's effects (p50/p99/max); worst adds the longest "
              f"instruction ({costs.sample_wait_max.cycles} cycles) and its listings' fetch and "
              f"CAN buffer waits (rprs listing), which are not simulated")
    con.print(f"vec: the MB90540/545 vector (ICR = (vec - 11) // 2; firmware_model/interrupts.py)"
              f"; each call costs entry {costs.entry.cycles} + RETI {costs.reti.cycles} "
              f"({costs.entry.source.split(':')[0]}) and its body, from these rows of the "
              f"cycle-cost table (docs/cpu.md; docs/fidelity.md says which are sourced):")
    named = sorted({h["handler"]: h for rep in out.values() for h in rep["handlers"]}.items(),
                   key=lambda kv: (kv[1]["level"], kv[0]))
    for name, h in named:
        rows = ", ".join(f"{row} {c['cycles']} ({c['source']})" for row, c in h["costs"].items())
        con.print(f"  {name}: {rows or 'none'}")
    return out
