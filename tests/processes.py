"""Helpers for tests that run robots as real processes on the pty radio hub: start and stop
``rprs`` processes, wait for a condition with a deadline, and read the ring off a sniffer."""
from __future__ import annotations

import contextlib
import subprocess
import sys
import time
from pathlib import Path


def spawn(*args: str, stdout=subprocess.DEVNULL) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "hil.cli", *args],
                            stdout=stdout, stderr=subprocess.PIPE, text=True)


def stop(procs) -> list[str]:
    """Terminate ``procs``, kill any still running after 5 s, and reap them all; returns what
    was left unread on each one's stderr pipe ("" without one) and closes its stdin and stderr.
    A Popen collected before its process was reaped, or with a pipe open, warns
    (ResourceWarning). Its stdout is left to whoever reads it (a reader thread closes it at
    its end)."""
    procs = list(procs)
    for p in procs:
        if p.poll() is None:
            p.terminate()
    rest = []
    for p in procs:
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(timeout=10)
        if p.stdin is not None:
            p.stdin.close()
        err = ""
        if p.stderr is not None and not p.stderr.closed:     # (stopped twice: closed)
            with p.stderr:
                err = p.stderr.read()
        rest.append(err)
    return rest


def sigstop(p: subprocess.Popen, timeout: float = 10.0) -> None:
    """Stop ``p`` (SIGSTOP) and return once every thread of it has stopped (state T in
    /proc). kill() returning is not enough: SIGSTOP wakes one thread, which then stops the
    others, and on a busy machine another thread may go on reading a port for milliseconds
    until it is scheduled."""
    import os
    import signal
    p.send_signal(signal.SIGSTOP)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        states = []
        with contextlib.suppress(FileNotFoundError):
            for task in os.listdir(f"/proc/{p.pid}/task"):
                with contextlib.suppress(FileNotFoundError):     # a thread that ended
                    with open(f"/proc/{p.pid}/task/{task}/stat") as f:
                        states.append(f.read().rsplit(")", 1)[1].split()[0])
        if states and all(s == "T" for s in states):
            return
        time.sleep(0.001)
    raise AssertionError(f"process {p.pid} did not stop within {timeout} s of SIGSTOP")


def wait_for(pred, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.05)
    return pred()


def ring_is(sniffer, robots) -> bool:
    """The last frames heard go round ``robots`` in order, twice: the ring is stable."""
    fs = sniffer.snapshot()[-2 * len(robots):]
    seq = [f.src for f in fs]
    return len(seq) == 2 * len(robots) and sorted(set(seq)) == sorted(robots) and all(
        b == robots[(robots.index(a) + 1) % len(robots)] for a, b in zip(seq, seq[1:]))


def heard(sniffer, robot, since=0.0) -> int:
    t0 = since * 16_000_000
    return sum(1 for f in sniffer.snapshot() if f.src == robot and f.start >= t0)


HOST_LATE_MS = 20.0
"""How late (ms) a bench process may run, by its own measure, before a wall-clock run counts
as disturbed: the real-time set's quiet gap, a quarter of its Tslot. The margins that R-stagger
leaves robot 6 (docs/protocol.md §7.6: 85.8 ms for the two pty hops and the timers) absorb one
such delay, not several in a row."""

ATTEMPTS = 3
"""Runs of a wall-clock scenario in all when a run fails and was disturbed (``disturbed``)."""


def disturbed(events, hub_lates=(), probe=None) -> list[str]:
    """Why a run on the hub did not get the CPU its margins assume, in words (empty: it did):
    every ``stall`` (a process that did not run for more than Tslot) and ``late`` (a timer run
    more than 20 ms late) event of the children's ``--events`` lines ``events`` (one list of
    dicts per child), the hub's own timers run late (``RealTimeScheduler.lates``: (due tick,
    ticks late)), and the host's worst wake-up (``hostload.SchedulingLatency``) past
    ``HOST_LATE_MS``. A failed check of a run with none of these is the product's."""
    why = [f"robot {e['robot']}: {e['ev']} {e['late'] / 16_000:.1f} ms"
           for ls in events for e in ls if e.get("ev") in ("stall", "late")]
    why += [f"the hub: a timer {late / 16_000:.1f} ms late" for _, late in hub_lates]
    if probe is not None:
        lat = probe.stop()
        if lat.max_ms > HOST_LATE_MS:
            why.append(str(lat))
    return why


@contextlib.contextmanager
def hub_links(link_dir, nodes: int, timeout: float = 20.0):
    """``rprs radio-hub --nodes N --link-dir DIR`` running while the block runs, its node
    links made (AssertionError if they do not come within ``timeout`` s); stopped after."""
    from paths import ROOT
    hub = subprocess.Popen([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes",
                            str(nodes), "--link-dir", str(link_dir)], cwd=ROOT,
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        last = Path(link_dir) / f"node{nodes - 1}"
        assert wait_for(last.exists, timeout), f"the hub made no {last}"
        yield hub
    finally:
        hub.terminate()
        hub.communicate(timeout=10)
