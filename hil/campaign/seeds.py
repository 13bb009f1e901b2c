"""Seeds of a campaign's runs, each repeatable alone.

Run ``i`` of grid point ``P`` gets the first 32-bit word of numpy's
``SeedSequence(root_seed, spawn_key=(h(P.key), i))``, ``h`` the first 64 bits of the SHA-256 of
the point's canonical parameter text: the point and the seed index name the stream, so adding
points or seeds to a grid never changes the seed of a run already made, and
``rprs sim <P's arguments> --seed <that word>`` repeats the run exactly (the simulator is
deterministic for a seed).
"""
from __future__ import annotations

import hashlib

from numpy.random import SeedSequence


def point_hash(point_key: str) -> int:
    """64 bits of SHA-256 of the point's canonical text."""
    return int.from_bytes(hashlib.sha256(point_key.encode()).digest()[:8], "big")


def run_seed(root_seed: int, point_key: str, index: int) -> int:
    """The ``--seed`` of run ``index`` of the point whose canonical text is ``point_key``."""
    ss = SeedSequence(root_seed, spawn_key=(point_hash(point_key), index))
    return int(ss.generate_state(1)[0])


def run_key(point_key: str, index: int) -> str:
    """The run's identity in the results database."""
    return f"{point_hash(point_key):016x}/{index}"
