"""Helpers for tests that run robots as real processes on the pty radio hub: start and stop
``rprs`` processes, wait for a condition with a deadline, and read the ring off a sniffer."""
from __future__ import annotations

import subprocess
import sys
import time


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
