"""The radio station's observers (firmware_model/station.py): a list, as python-can's
Notifier keeps its listeners, not a slot each newcomer wraps and reassigns."""
from __future__ import annotations

import pytest

from firmware_model.mcu.scheduler import Scheduler
from firmware_model.radio.mac import Message
from firmware_model.radio.content import cmd
from firmware_model.station import build_station


def _station(observer=None):
    return build_station(1, Scheduler(), observer=observer)[0]


def test_observers_are_told_in_order_and_first_goes_before_them():
    told = []
    st = _station(lambda s, a, now: told.append("built"))
    st.add_observer(lambda s, a, now: told.append("second"))
    st.add_observer(lambda s, a, now: told.append("front"), first=True)
    st.mac.power_on(0)
    msg = st.submit(2, [cmd("status")])
    assert type(msg) is Message
    assert told == ["front", "built", "second"]
    assert len(st.observers) == 3


def test_a_removed_observer_is_told_nothing_and_the_notifier_is_stable_until_a_change():
    told = []

    def mine(s, a, now):
        told.append(a)
    st = _station()
    assert st.observer is None and st.observers == ()
    st.add_observer(mine)
    assert st.observer is mine                         # one observer: called directly
    st.add_observer(print)
    both = st.observer
    assert both is st.observer and both not in (mine, print)
    st.remove_observer(print)
    st.remove_observer(mine)
    assert st.observer is None
    st.mac.power_on(0)
    st.submit(2, [cmd("status")])
    assert told == []
    with pytest.raises(ValueError):
        st.remove_observer(mine)


def test_the_application_side_is_a_list_told_each_delivery_in_order_before_the_observers():
    from firmware_model.radio.mac import Deliver
    from hil.sim.world import SimConfig, World
    w = World(SimConfig(robots=(0, 1), duration=4.0, seed=1, load=3.0, can=True))
    st = w.stations[1]
    wake, child = st.apps        # the simulator's CAN-side wake first, then the dispatcher
    assert child == w.children[1]._on_message
    told = []
    st.add_app(lambda d, now: told.append(("front", d.num)), first=True)
    st.add_app(lambda d, now: told.append(("back", d.num)))
    st.add_observer(lambda s, a, now: told.append(("observer", a.num))
                    if type(a) is Deliver else None)
    w.run()
    nums = [n for who, n in told if who == "front"]
    assert len(nums) > 3
    assert told == [(who, n) for n in nums for who in ("front", "back", "observer")]
    st.remove_app(child)
    assert len(st.apps) == 3 and child not in st.apps and st.apps[1] is wake
    with pytest.raises(ValueError):
        st.remove_app(child)
