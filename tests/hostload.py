"""How late this host wakes a sleeping process, measured while a wall-clock test runs.

A robot process on the pty hub sleeps until its next byte or timer and is woken by the
kernel; on a busy machine (other programs, other engineers' builds, the other xdist worker)
it runs late by the time it waits for a core. ``SchedulingLatency`` runs a small process of
its own beside the test that sleeps 2 ms at a time and records how late each wake-up came:
the same delay a robot process sees. A test scales its timing tolerances by it (``slack_ms``)
and names it in its failure message, so that a failure says whether the product was late or
the host was busy.
"""
from __future__ import annotations

import json
import statistics
import subprocess
import sys
from dataclasses import dataclass

_PROBE = r"""
import json, select, sys, time
late = []
while True:
    t = time.monotonic()
    if select.select([sys.stdin], [], [], 0.002)[0]:
        break                                   # stdin closed: the test is done
    late.append((time.monotonic() - t - 0.002) * 1000)
print(json.dumps(late))
"""


@dataclass(frozen=True)
class Latency:
    """How late the probe's wake-ups came, in ms: median, 90th and 99th percentile, worst."""

    samples: int
    median_ms: float
    p90_ms: float
    p99_ms: float
    max_ms: float

    def __str__(self) -> str:
        return (f"host scheduling latency over {self.samples} wake-ups: median "
                f"{self.median_ms:.2f} ms, p90 {self.p90_ms:.2f} ms, p99 {self.p99_ms:.2f} ms, "
                f"worst {self.max_ms:.1f} ms")


def summarise(late_ms: list[float]) -> Latency:
    if not late_ms:
        return Latency(0, 0.0, 0.0, 0.0, 0.0)
    s = sorted(max(0.0, x) for x in late_ms)

    def pct(p: float) -> float:
        return s[min(len(s) - 1, int(p / 100 * len(s)))]
    return Latency(len(s), statistics.median(s), pct(90), pct(99), s[-1])


class SchedulingLatency:
    """``with SchedulingLatency() as probe: ...``; then ``probe.result`` (a ``Latency``).
    ``probe.stop()`` ends the measurement early and returns it."""

    def __init__(self) -> None:
        self.result: Latency | None = None
        self._proc: subprocess.Popen | None = None

    def __enter__(self) -> "SchedulingLatency":
        self._proc = subprocess.Popen([sys.executable, "-c", _PROBE], stdin=subprocess.PIPE,
                                      stdout=subprocess.PIPE, text=True)
        return self

    def stop(self) -> Latency:
        if self.result is None and self._proc is not None:
            out, _ = self._proc.communicate(timeout=30)      # closes its stdin: it reports
            self.result = summarise(json.loads(out) if out.strip() else [])
        assert self.result is not None, "the probe was never started"
        return self.result

    def __exit__(self, *exc: object) -> None:
        try:
            self.stop()
        except Exception:
            if self._proc is not None and self._proc.poll() is None:
                self._proc.kill()
                self._proc.wait()
            if exc[0] is None:
                raise
