"""A campaign's own metrics for tests/hil/test_campaign.py (``[campaign] metrics =
"campaign_metrics:frames"``): a module a worker can import, as a user's would be."""
from __future__ import annotations


def frames(events, world) -> dict[str, float]:
    """Frames on air and the share of them that collided, from the run's trace events; the
    world's own count beside them (a check that both are the run's)."""
    from hil.sim import events as E
    on_air = [e for e in events if type(e) is E.FrameOnAir]
    return {"frames on air": len(on_air),
            "collided share": sum(e.collided for e in on_air) / len(on_air) if on_air else 0.0,
            "occupations": world.air.occupations}


def not_a_number(events, world):
    return {"frames": "many"}
