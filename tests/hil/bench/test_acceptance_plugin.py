"""The acceptance plugin's own reports (hil/bench/acceptance.py): a failed expectation says
what the bench saw, not just "assert False"."""
from __future__ import annotations

from firmware_model.radio.content import cmd
from hil.bench.acceptance import ModelDut


def test_explain_says_what_became_of_the_fathers_message_and_what_the_robot_sent():
    d = ModelDut(1)
    try:
        assert d.run_until(d.in_ring, 30.0)
        ok = d.send([cmd("status")])
        assert d.run_until(lambda: ok.state == "delivered" and d.replies(), 10.0)
        lost = d.send([cmd("status")], dst=3)            # no robot 3 on this bench
        assert d.run_until(lambda: lost.state == "failed", 10.0)
        why = d.explain(lost)
    finally:
        d.close()
    assert why.startswith("the father's status(): failed (destination 3 not in the ring); "
                          "robot 1 sent the father 1 messages, the last Type '3' joint(1,"), why
    assert "no longer in the father's ring" not in why
