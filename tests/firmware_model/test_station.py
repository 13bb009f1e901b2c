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
