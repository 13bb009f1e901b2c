"""The ``.log`` of ``--can-log FILE.log`` (can_bus/candump_log.py): every line as can-utils'
``candump -L`` writes it, read back by can-utils' ``log2asc`` where it is installed."""
from __future__ import annotations

import shutil
import subprocess

import can
import pytest

from can_bus.candump_log import CandumpLogWriter


def _written(tmp_path, messages) -> tuple[list[str], CandumpLogWriter]:
    path = tmp_path / "bus.log"
    w = CandumpLogWriter(str(path), channel="vcan0")
    for m in messages:
        w.on_message_received(m)
        # each line is on disk as it is written (a process killed by SIGKILL lost ~2 s)
        assert path.read_text().count("\n") == len(path.read_text().splitlines())
    lines = path.read_text().splitlines()
    w.stop()
    return lines, w


def test_every_frame_is_written_as_candump_writes_it(tmp_path):
    """candump -L (can-utils lib.c sprint_canframe) against what python-can's writer wrote:
    a remote frame's DLC (R6; above 8, R8_C), a classic frame's raw DLC above 8 (_C), an
    error frame's class (20000020 for CAN_ERR_ACK, where python-can wrote 20000080 for
    every class), a stamp that never goes back; and frames no candump line can hold (an
    11-bit id above 0x7FF, a DLC that disagrees with the data) left out, counted."""
    msgs = [
        can.Message(timestamp=10.0, arbitration_id=0x101, is_extended_id=False,
                    is_remote_frame=True, dlc=6, is_rx=True),
        can.Message(timestamp=10.1, arbitration_id=0x103, is_extended_id=False,
                    is_remote_frame=True, dlc=12, is_rx=True, check=False),
        can.Message(timestamp=10.05, arbitration_id=0x181, is_extended_id=False,
                    data=bytes(range(8)), dlc=13, is_rx=False, check=False),
        can.Message(timestamp=10.2, arbitration_id=0x20, is_error_frame=True, dlc=8,
                    data=bytes(8)),
        can.Message(timestamp=10.3, arbitration_id=0x1ABCDEF, is_extended_id=True,
                    data=b"\x01", is_rx=True),
        can.Message(timestamp=10.4, arbitration_id=0x123, is_extended_id=False, is_fd=True,
                    bitrate_switch=True, data=bytes(12), is_rx=True),
        can.Message(timestamp=10.5, arbitration_id=0x901, is_extended_id=False,
                    data=bytes(2), is_rx=True, check=False),
        can.Message(timestamp=10.6, arbitration_id=0x105, is_extended_id=False,
                    data=bytes(6), dlc=2, is_rx=True, check=False),
    ]
    lines, w = _written(tmp_path, msgs)
    assert lines == [
        "(10.000000) vcan0 101#R6 R",
        "(10.100000) vcan0 103#R8_C R",
        "(10.100000) vcan0 181#0001020304050607_D T",     # 10.05 < 10.1: held
        "(10.200000) vcan0 20000020#0000000000000000",
        "(10.300000) vcan0 01ABCDEF#01 R",
        "(10.400000) vcan0 123##5000000000000000000000000 R",
    ]
    assert w.unwritable == 2


def test_a_gzipped_log_holds_the_same_candump_lines(tmp_path):
    """``--can-log FILE.log.gz`` went to python-can's compressed writer, whose lines are not
    candump's (a remote frame's DLC lost, every error class a bus error): it is the same
    writer as a ``.log``, through gzip."""
    import gzip
    from can_bus.candump_log import open_log
    msgs = [can.Message(timestamp=1.0, arbitration_id=0x101, is_extended_id=False,
                        is_remote_frame=True, dlc=6, is_rx=True, channel="vcan0"),
            can.Message(timestamp=1.1, arbitration_id=0x20, is_error_frame=True, dlc=8,
                        data=bytes(8), channel="vcan0")]
    w = open_log(str(tmp_path / "bus.log.gz"))
    for m in msgs:
        w.on_message_received(m)
    w.stop()
    with gzip.open(tmp_path / "bus.log.gz", "rt") as f:
        assert f.read().splitlines() == ["(1.000000) vcan0 101#R6 R",
                                         "(1.100000) vcan0 20000020#0000000000000000"]


@pytest.mark.skipif(shutil.which("log2asc") is None,
                    reason="log2asc not installed (Debian package can-utils)")
def test_can_utils_reads_the_whole_log(tmp_path):
    """One frame no candump line holds (an 11-bit id above 0x7FF, written 1234#02) stopped
    log2asc at that line: every frame after it was lost to the converted file."""
    msgs = [can.Message(timestamp=1.0 + i / 10, arbitration_id=i, is_extended_id=False,
                        data=bytes([i]), is_rx=True) for i in range(1, 4)]
    msgs.insert(1, can.Message(timestamp=1.15, arbitration_id=0x1234, is_extended_id=False,
                               data=b"\x02", is_rx=True, check=False))
    msgs.append(can.Message(timestamp=1.5, arbitration_id=0x103, is_extended_id=False,
                            is_remote_frame=True, dlc=12, is_rx=True, check=False))
    _written(tmp_path, msgs)
    r = subprocess.run(["log2asc", "-I", str(tmp_path / "bus.log"), "vcan0"],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode == 0, r.stderr
    body = [x for x in r.stdout.splitlines() if x.strip() and x.split()[0][0].isdigit()]
    assert len(body) == 4, r.stdout                  # 1, 2, 3 and the remote frame
