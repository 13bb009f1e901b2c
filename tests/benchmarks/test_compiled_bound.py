"""benchmarks/compiled_bound.py: own time by module from py-spy's raw output, and the Amdahl
bound of compiling a group of modules."""
from __future__ import annotations

import importlib.util

import pytest
from paths import ROOT

_spec = importlib.util.spec_from_file_location("compiled_bound",
                                               ROOT / "benchmarks" / "compiled_bound.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

RAW = [
    # imports and the world's construction: outside World.run, not counted
    "<module> (<string>:1);<module> (/src/can_bus/bus.py:3) 50\n",
    "<module> (<string>:1);World.run (/src/hil/sim/world.py:424);"
    "Scheduler.run_until (/src/firmware_model/mcu/scheduler.py:145) 10\n",
    "<module> (<string>:1);World.run (/src/hil/sim/world.py:424);"
    "Scheduler.run_until (/src/firmware_model/mcu/scheduler.py:145);"
    "CanBus._arbitrate (/src/can_bus/bus.py:600) 30\n",
    "<module> (<string>:1);World.run (/src/hil/sim/world.py:424);"
    "Scheduler.run_until (/src/firmware_model/mcu/scheduler.py:145);"
    "Air._end (/src/hil/sim/air.py:588) 40\n",
    "<module> (<string>:1);World.run (/src/hil/sim/world.py:424);"
    "Scheduler.run_until (/src/firmware_model/mcu/scheduler.py:145);"
    "Event.__init__ (/src/hil/sim/world.py:90) 20\n",
    "\n",
]


def test_own_time_takes_the_innermost_frame_inside_the_run_only():
    samples = bench.own_time(RAW, "/src")
    assert samples == {"firmware_model/mcu/scheduler.py": 10, "can_bus/bus.py": 30,
                       "hil/sim/air.py": 40, "hil/sim/world.py": 20}


def test_shares_and_the_amdahl_bound():
    shares = bench.group_shares(bench.own_time(RAW, "/src"))
    assert shares["scheduler"] == pytest.approx(0.1)
    assert shares["CAN bus"] == pytest.approx(0.3)
    assert shares["radio path"] == pytest.approx(0.4)
    assert shares["the rest"] == pytest.approx(0.2)
    assert sum(shares.values()) == pytest.approx(1.0)
    # scheduler and CAN bus for free: 60 % of the time is left, 1/0.6
    assert bench.bound(shares, ("scheduler", "CAN bus")) == pytest.approx(1 / 0.6)
    assert bench.bound(shares, ()) == 1.0
    assert bench.bound({"all": 1.0}, ("all",)) == float("inf")


@pytest.mark.skipif(bench.py_spy() is None,
                    reason="py-spy is not installed (pip install -e '.[bench]')")
def test_a_real_profile_charges_the_run_to_its_modules():
    # An hour of the ring: about 600 samples at 200 Hz (a minute gave about 11, and a share
    # of 11 samples swings from 0.3 to 0.8 between runs). The radio path's share is about 0.7,
    # so 0.5 is some eight standard deviations below it at 600 samples.
    code = ("from hil.sim.world import SimConfig, World\n"
            "World(SimConfig(robots=(1, 2, 3), duration=3600, ring_sleep=False)).run()\n")
    samples = bench.profile(code, 200, str(ROOT))
    shares = bench.group_shares(samples)
    assert sum(samples.values()) >= 200
    assert shares["radio path"] > 0.5          # a radio-only ring is mostly its radio path
    assert shares["CAN bus"] == 0.0            # and has no CAN side at all
