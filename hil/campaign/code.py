"""The code a campaign's process runs, as one digest: what every row records and what the
engine compares between the client and each worker before the runs are sent
(docs/campaigns.md, "Resumable and honest")."""
from __future__ import annotations

import functools
import hashlib
from pathlib import Path

PACKAGES = ("firmware_model", "can_bus", "hil")
"""The packages whose sources make the digest (the simulator's code, all of it)."""
SUFFIXES = (".py", ".lua", ".dbc")


@functools.lru_cache(maxsize=1)
def code_identity(root: str | None = None) -> str:
    """16 hex digits of the SHA-256 of the packages' source files (each file's path relative
    to the packages' folder, then its bytes, in path order), as this process imports them:
    two processes with the same digest run the same simulator."""
    base = Path(root) if root is not None else Path(__file__).resolve().parents[2]
    h = hashlib.sha256()
    for pkg in PACKAGES:
        for path in sorted((base / pkg).rglob("*")):
            if path.suffix in SUFFIXES and "__pycache__" not in path.parts and path.is_file():
                h.update(path.relative_to(base).as_posix().encode() + b"\0")
                h.update(path.read_bytes() + b"\0")
    return h.hexdigest()[:16]
