"""The opt-in checksum extension (docs/protocol.md §3.4, docs/mac.md): test vectors and interop."""
from __future__ import annotations

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
