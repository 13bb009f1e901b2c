"""hil/sim/config.py: a SimConfig is checked whole by ``validate``, whoever builds it (``rprs
sim``, the campaign, the soak, a script): the settings that do not go together are refused
through the Python API as ``rprs sim`` refuses them, and a campaign refuses a grid point that
``rprs sim`` would refuse before it runs one."""
from __future__ import annotations

import pytest

import hil.sim.config
import hil.sim.world
from firmware_model.radio.auth import RingKey
from firmware_model.radio.mac import MacConfig
from firmware_model.radio.peer_macs import PeerConfig
from hil.campaign.runs import check_args
from hil.campaign.spec import SpecError, load_spec
from hil.sim.config import ConfigError, SimConfig
from hil.sim.faults import Fault, parse_fault


def test_the_world_module_still_offers_the_config():
    assert hil.sim.world.SimConfig is hil.sim.config.SimConfig
    assert hil.sim.world.ConfigError is hil.sim.config.ConfigError


@pytest.mark.parametrize("settings,words", [
    ({"robots": (0, 1), "father_standby": True, "mac": MacConfig(profile="paper")},
     "--profile paper has no standby PC"),
    ({"mac_kind": "aloha", "mac": MacConfig(profile="paper")},
     "--profile paper is a profile of the rotational MAC"),
    ({"mac_kind": "csma", "faults": (parse_fault("steal:2@3"),)},
     "--fault steal:2@3: --mac csma has no turns to steal"),
    ({"mac_kind": "slotted", "mac": MacConfig(auth=RingKey(bytes(16)))},
     "--auth-key: --mac slotted has no authenticated profile"),
    ({"mac_kind": "aloha", "robots": (0, 1), "father_standby": True},
     "--father-standby needs the rotational MAC"),
    ({"peer": PeerConfig(frame_bytes=100)}, "sizes the peer MACs' frames"),
])
def test_settings_that_do_not_go_together_are_a_config_error(settings, words):
    """These were refused only by ``rprs sim``'s option handling (hil/cli/sim.py): a
    SimConfig built in Python with them ran, and did nothing with the setting."""
    with pytest.raises(ConfigError, match=words):
        SimConfig(duration=5.0, **settings).validate()


@pytest.mark.parametrize("power_on,words", [
    ({5: 1.0}, r"a power-on time for robot 5, which is not in the ring \[1, 2, 3, 4\]"),
    ({2: -1.0}, "bad power-on time -1.0 for robot 2"),
    ({2: float("nan")}, "robot 2's power-on time must be a finite number, got nan")])
def test_a_power_on_time_says_what_is_wrong_with_it(power_on, words):
    """``--power 5@1`` on a ring without robot 5 said "bad power-on time 1.0 for robot 5",
    blaming the time; a NaN time passed (``t < 0`` is False for it)."""
    with pytest.raises(ConfigError, match=words):
        SimConfig(duration=5.0, power_on=power_on).validate()


def test_the_same_settings_alone_are_good():
    for settings in ({"robots": (0, 1), "father_standby": True},
                     {"mac": MacConfig(profile="paper")},
                     {"faults": (parse_fault("steal:2@3"),)},
                     {"mac_kind": "aloha", "peer": PeerConfig(frame_bytes=100)}):
        SimConfig(duration=5.0, **settings).validate()


def test_a_campaign_refuses_a_point_that_rprs_sim_refuses(tmp_path):
    """``rprs sim --robots 1,2 --fault fail:3@1`` is refused (robot 3 is not in the ring);
    the campaign checked its points with the option handling only and took it, to record
    every one of its runs as crashed."""
    spec = tmp_path / "c.toml"
    spec.write_text("[campaign]\nseeds = 2\n[grid]\nrobots = ['1,2']\nduration = [2]\n"
                    "fault = [[], ['fail:3@1']]\n")
    with pytest.raises(SpecError, match="names robot 3, which is not in the ring"):
        load_spec(spec, check=check_args)
    spec.write_text("[campaign]\nseeds = 2\n[grid]\nrobots = ['1,2']\nduration = [2]\n"
                    "fault = [[], ['fail:2@1']]\n")
    assert load_spec(spec, check=check_args).runs == 4


def test_one_switch_turns_every_fast_path_off():
    """``SimConfig(fast_paths=False)`` (``rprs sim --every-frame``): no ring leaps, no sleeping
    CAN side, every MAC on its general path; the default has all three (docs/performance.md,
    "How the fast paths work")."""
    from hil.sim.world import World
    slow = World(SimConfig(robots=(0, 1, 2), duration=1, can=True, fast_paths=False))
    assert slow.quiet_ring is None
    assert slow.quiet and not any(q.enabled for q in slow.quiet.values())
    assert all(not st.mac.cfg.fast_path for st in slow.stations.values())
    fast = World(SimConfig(robots=(0, 1, 2), duration=1, can=True))
    assert fast.quiet_ring is not None and all(q.enabled for q in fast.quiet.values())
    assert all(st.mac.cfg.fast_path for st in fast.stations.values())


@pytest.mark.parametrize("cpu", ["estimated", "ideal", 1])
def test_a_cpu_that_is_no_cost_table_says_so(cpu):
    """``SimConfig(cpu="estimated")``, the command line's word, got as far as building the
    CPUs and died there in an AttributeError."""
    with pytest.raises(ConfigError, match="cpu must be a CycleCosts or None"):
        hil.sim.world.World(SimConfig(duration=1.0, cpu=cpu))


def test_the_cost_table_and_the_ideal_cpu_are_good():
    from firmware_model.cycle_costs import DEFAULT_COSTS
    for cpu in (None, DEFAULT_COSTS):
        SimConfig(duration=1.0, cpu=cpu).validate()


@pytest.mark.parametrize("settings,words", [
    ({"load": float("inf")}, "load must be a finite number"),
    ({"load": 1e6}, "more than 1000"),                 # ran for ever (a message a microsecond)
    ({"duration": "10"}, "duration must be a finite number"),
    ({"ber": None}, "ber must be a finite number"),
    ({"robots": 3}, "robots must be a tuple"),
    ({"robots": (True, 2)}, "robot ID True is not 0-6"),
    ({"power_on": {1: "2"}}, "robot 1's power-on time must be a finite number"),
    ({"faults": ("fail:1@2",)}, "faults must be Fault objects"),
    ({"faults": (Fault("zap", 1, 0.5),)}, "unknown fault kind 'zap'"),
    ({"faults": (Fault("ber", None, 0.5, 1.0),)}, "ber needs a probability"),
    ({"faults": (Fault("fail", None, 0.5),)}, "fail needs a robot"),
    ({"faults": (Fault("fail", 1, float("nan")),)}, "time must be a finite number"),
    ({"faults": (Fault("skew", 1),)}, "a skew needs its fraction"),
    ({"extra": ((),)}, "each extra robot must be"),
    ({"mac": {"checksum": True}}, "mac must be a MacConfig"),
    ({"sequence": ((1, 2),)}, "sequence must be"),
    ({"load": "saturate", "payload": 0}, "payload must be 8-562"),
    ({"load": "saturate", "payload": "5"}, "payload must be a whole number"),
    ({"load_until": "x"}, "load_until must be a finite number"),
    ({"can": "no"}, "can must be True or False"),
])
def test_a_setting_of_the_wrong_type_is_a_config_error(settings, words):
    """A program's SimConfig is not typed by the command line's options: each of these used
    to die deep in the run (TypeError, AttributeError, OverflowError), hang, or run taking
    "no" for yes or an unknown fault for nothing."""
    with pytest.raises(ConfigError, match=words):
        hil.sim.world.World(SimConfig(**{"duration": 2.0, **settings}))
