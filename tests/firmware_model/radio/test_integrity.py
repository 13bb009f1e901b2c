"""The opt-in checksum extension (docs/protocol.md §3.4, docs/mac.md): test vectors and interop."""
from __future__ import annotations

import pytest

from firmware_model.radio.content import parse_content, split_layers
from firmware_model.radio.frame import Frame, parse_frame
from firmware_model.radio.integrity import CRC_TEXT_LEN, check, crc16, seal, strip


def test_crc16_ccitt_false_check_value():
    assert crc16(b"123456789") == 0x29B1 == 10673
    assert crc16(b"") == 0xFFFF


def test_sealed_frame_vector():
    f = seal(2, 1, 5, 2, b"movex(10)")
    assert f.encode() == b"\x0f\x0a\x05" + b"21052" + b"0019" + b"movex(10)crc(18422)" + \
        b"\x17\x19"
    assert check(f) and strip(f.content) == b"movex(10)"
    assert len(f.content) == 9 + CRC_TEXT_LEN


def test_any_single_bit_error_in_the_covered_bytes_is_caught():
    data = bytearray(seal(3, 4, 77, 2, b"joint(2,45)moveto(1.5,-2,0)").encode())
    for i in range(3, len(data) - 2 - CRC_TEXT_LEN):       # Destination .. last Content byte
        for bit in range(8):
            bad = bytearray(data)
            bad[i] ^= 1 << bit
            try:
                f = parse_frame(bytes(bad))
            except ValueError:
                continue                                   # the deframer refuses it already
            assert not check(f), (i, bit)


def test_frames_without_or_with_a_bad_checksum_fail():
    assert not check(Frame(dst=2, src=1, num=5, type=2, content=b"movex(10)"))
    assert not check(Frame(dst=2, src=1, num=5, type=2, content=b"movex(10)crc(00000)"))
    assert not check(Frame(dst=2, src=1, num=5, type=2, content=b"crc(1)"))


def test_paper_format_receivers_still_parse_a_sealed_frame():
    f = seal(2, 1, 5, 2, b"movex(10)")
    mac, app = split_layers(parse_content(f.content))
    assert [c.text() for c in app] == ["movex(10)"] and mac[0].name == "crc"


def _member_waiting_for_robot_1(checksum: bool):
    """R2 invited into ring (1, 2) by R1, its own first frame sent: it waits for R1's turn."""
    from firmware_model.radio.mac import MacConfig, RotationalMac
    mac = RotationalMac(2, MacConfig(checksum=checksum))
    mac.power_on(0)
    poll = seal(7, 1, 5, 3, b"poll(2,2)") if checksum else \
        Frame(dst=7, src=1, num=5, type=3, content=b"poll(2,2)")
    mac.on_frame(poll, 0, 1000, 1000)
    mac.on_timer(mac.deadline)
    mac.on_tx_done(2_000_000)
    assert (mac.phase, mac.owner) == ("wait", 1)
    return mac


def test_with_the_extension_on_the_owners_heartbeat_without_a_checksum_is_refused():
    """docs/protocol.md §3.4: a receiver with the extension on refuses a frame whose checksum
    is missing, the turn owner's empty heartbeat too (it once took a fast path that did not
    look): the turn is not handed on."""
    from firmware_model.radio.mac import BadChecksum, TxEnable
    t = 3_000_000
    mac = _member_waiting_for_robot_1(checksum=True)
    out = mac.on_frame(Frame(dst=7, src=1, num=5, type=3, content=b""), t, t + 1000, t + 1000)
    assert [type(a) for a in out] == [BadChecksum]          # no TxEnable: not our turn
    assert mac.phase != "switch"
    sealed = seal(7, 1, 6, 3, b"")
    out = _member_waiting_for_robot_1(checksum=True).on_frame(sealed, t, t + 1000, t + 1000)
    assert any(isinstance(a, TxEnable) for a in out)       # the sealed heartbeat hands it on
    mac = _member_waiting_for_robot_1(checksum=False)
    out = mac.on_frame(Frame(dst=7, src=1, num=5, type=3, content=b""), t, t + 1000, t + 1000)
    assert any(isinstance(a, TxEnable) for a in out)       # extension off: a plain heartbeat


def test_with_the_extension_on_a_bad_checksum_is_judged_before_the_source_it_names():
    """Clause 43: with the checksum on, a frame whose checksum fails is a failed frame whose
    Source was not read. A byte error that turns the Source into our own ID, or into a robot
    outside the team, must not be taken for a twin (clause 38) or a foreign ring: two such
    frames once made a member announce a duplicate ID and leave for LISTEN."""
    from firmware_model.radio.mac import (BadChecksum, DuplicateId, ForeignRing, ModeChange,
                                          Refused)
    mac = _member_waiting_for_robot_1(checksum=True)
    t = 3_000_000
    events = []
    for src in (2, 2, 5, 2):                     # our own ID twice, one outside (1, 2), again
        good = seal(7, 1, 6, 3, b"")
        forged_src = Frame(dst=7, src=src, num=good.num, type=3, content=good.content)
        events += list(mac.on_frame(forged_src, t, t + 1000, t + 1000))
        t += 700_000
    kinds = {type(e) for e in events}
    assert BadChecksum in kinds, events
    assert not kinds & {DuplicateId, ForeignRing, Refused}, events
    assert not [e for e in events if isinstance(e, ModeChange)], events
    assert mac.mode == "member"


def test_a_refused_good_frame_proves_the_radio_hears_and_resets_the_cut_off_count():
    """Clause 40: a member goes to LISTEN after max(3, n - 1) misses "without hearing any good
    frame in between". A good frame it refuses (our own ID, here) was heard: its radio is not
    cut off. Robot 2 of ring (1, 2, 3), after its own frame: robots 3 and 1 miss, our own ID
    is heard, robot 3 misses: three misses, not in a row, and R2 stays a member."""
    from firmware_model.radio.mac import MacConfig, Miss, ModeChange, Refused, RotationalMac
    mac = RotationalMac(2, MacConfig(team=frozenset({1, 2, 3})))
    mac.power_on(0)
    t = 1_000_000
    mac.on_frame(Frame(dst=7, src=1, num=5, type=3, content=b"poll(2,10)"), t - 20_000, t, t)
    mac.on_timer(mac.deadline)                  # SWITCH: our JOIN goes out
    mac.on_tx_done(mac.turn_start + 2_000_000)
    assert (mac.mode, mac.ring, mac.owner) == ("member", (1, 2, 3), 3)
    events = list(mac.on_timer(mac.deadline))   # robot 3 misses
    events += mac.on_timer(mac.deadline)        # robot 1 misses
    e = mac.turn_start + 100_000                # our own ID heard in robot 2's turn: refused
    events += mac.on_frame(Frame(dst=7, src=2, num=9, type=3, content=b""), e - 233_000, e, e)
    while mac.owner != 3 or mac.phase != "wait":
        events += mac.on_timer(mac.deadline)
    events += mac.on_timer(mac.deadline)        # robot 3 misses again
    assert [type(x) for x in events if isinstance(x, (Miss, Refused))] == \
        [Miss, Miss, Refused, Miss], events
    assert not [x for x in events if isinstance(x, ModeChange)], events
    assert mac.mode == "member"


@pytest.mark.parametrize("frame", [
    pytest.param(Frame(dst=7, src=5, num=1, type=3, content=b""), id="outside the team"),
    pytest.param(Frame(dst=7, src=1, num=1, type=3, content=b"crc(00000)"), id="bad checksum"),
])
def test_a_lone_member_stays_for_a_frame_refused_as_failed(frame):
    """Clause 31: a lone member goes back to LISTEN for a good frame of another robot of its
    team; a frame refused as a failed frame (Source outside the team, clause 38; bad checksum,
    clause 43) is none: its Source may be a byte error or a stranger's."""
    from firmware_model.radio.mac import MacConfig, ModeChange, RotationalMac
    mac = RotationalMac(2, MacConfig(team=frozenset({1, 2, 3}), checksum=True))
    mac.power_on(0)
    while mac.mode != "member":                  # silence: it claims, a ring of one
        mac.on_timer(mac.deadline)
    mac.on_timer(mac.deadline)
    mac.on_tx_done(mac.deadline if mac.deadline else mac.turn_start + 1_000_000)
    assert mac.ring == (2,)
    t = mac.turn_start + 2_000_000
    out = mac.on_frame(frame, t - 14 * 16_667, t, t)
    assert not [e for e in out if isinstance(e, ModeChange)], out
    assert (mac.mode, mac.ring) == ("member", (2,))
