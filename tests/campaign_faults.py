"""Faults for the campaign tests' workers (tests/hil/test_campaign.py), importable by a
worker process (``multiprocessing`` gives it the test process's ``sys.path``)."""
from __future__ import annotations

import os


def die_once(marker: str, cfg):
    """The first run to get here kills its worker process (as the kernel's OOM killer or a
    lost node would); every later run, on any worker, measures as usual."""
    from hil.campaign.runs import metrics_of
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return metrics_of(cfg)
    os.close(fd)
    os._exit(1)


def lose_first(marker: str, chunk, measure=None):
    """``run_chunk``, but the first task to get here fails as a task whose worker died does
    (the engine sees an exception from the task, not a run's result)."""
    from hil.campaign.runs import metrics_of, run_chunk
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return run_chunk(chunk, measure=measure or metrics_of)
    os.close(fd)
    raise OSError("the worker running this task died (a stand-in for KilledWorker)")


def lose_always(chunk, measure=None):
    """A task the cluster loses every time."""
    raise OSError("the worker running this task died (a stand-in for KilledWorker)")
