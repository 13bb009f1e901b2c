"""A radio port that goes away under a running robot (the radio hub stopped, a USB-serial
adapter pulled): the process stops with one line saying so and status 1, not silently with
the status of a Ctrl-C (docs/bench.md)."""
from __future__ import annotations

import os
import subprocess
import sys
import tty

from hil.bench.runner import Runner, build_father


def _pty() -> tuple[int, str]:
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.close(slave)
    return master, path


def test_a_lost_port_stops_the_runner_and_says_why():
    master, path = _pty()
    runner = Runner()
    build_father(runner, path)
    runner.sched.post(os.close, master)
    runner.run(60.0)                 # returns long before: the port is gone
    assert runner.failure is not None
    assert runner.failure.startswith(f"the radio port {path} went away (")


def test_rprs_child_whose_port_goes_away_exits_1_with_one_line():
    master, path = _pty()
    proc = subprocess.Popen([sys.executable, "-m", "hil.cli", "child", "--id", "1", "--radio",
                             path, "--team", "0,1"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        first = proc.stderr.readline()
        assert first.startswith("running child 1"), first
        os.close(master)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    lines = err.splitlines()
    assert proc.returncode == 1, err
    assert lines[-1].startswith(f"rprs: error: the radio port {path} went away"), err
    assert lines[-2].startswith("robot 1: ") and "Traceback" not in err


def test_a_radio_port_that_takes_no_bytes_is_said_and_exits_1():
    """A radio port whose far side stops taking bytes (a stopped ``rprs radio-hub``, Ctrl-Z
    on its terminal; a stalled ``socket://`` server): every frame's write timed out after 2 s
    and the frame was lost without a word, the summary counting it sent, exit status 0. Now
    the first failed write of a run says so in a line, and the exit status is 1."""
    master, path = _pty()
    slave = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        while True:                  # fill what the pty holds: the master is never read
            os.write(slave, bytes(1024))
    except BlockingIOError:
        pass
    try:
        r = subprocess.run([sys.executable, "-m", "hil.cli", "child", "--id", "1", "--radio",
                            path, "--team", "0,1", "--duration", "5"], capture_output=True,
                           text=True, timeout=120)
    finally:
        os.close(slave)
        os.close(master)
    lines = r.stderr.splitlines()
    assert r.returncode == 1, r.stderr
    said = [x for x in lines if x.startswith(f"rprs: the radio port {path}: cannot write")]
    assert len(said) == 1 and "the frame is lost" in said[0], r.stderr
    assert lines[-1].startswith("rprs: 1 trouble during the run") and "Traceback" not in r.stderr


def test_a_closer_that_raises_is_said_and_the_others_still_run(capsys):
    """Closing goes on past a part whose close raises (the rest still close: a log ended,
    a bus shut down), and says so in one line with exit status 1 (``troubles``): the
    exception used to be swallowed, hiding a CAN log left unended."""
    runner = Runner()
    closed = []
    runner.on_close(lambda: closed.append("first"))

    def broken() -> None:
        raise ValueError("CAN 2.0A id must be in 0..0x7FF, got 0x800")
    runner.on_close(broken)
    runner.run(0.01)
    assert closed == ["first"] and runner.troubles == 1
    assert capsys.readouterr().err == ("rprs: while closing: ValueError: CAN 2.0A id must be "
                                       "in 0..0x7FF, got 0x800\n")


def test_frames_failing_the_checksum_are_counted_and_said_once():
    """A father with ``--checksum`` on a ring without it heard 50 frames, "bad frames 0,
    refused 0", and never joined, with no word why. Frames failing the checksum (clause 43:
    failed frames) are counted in the closing line, and once every frame heard has failed
    it (three or more) the station says so in one line."""
    import io
    from firmware_model.radio.frame import Frame
    from firmware_model.radio.mac import MacConfig
    from firmware_model.station import build_station
    from hil.bench.runner import _events_printer, summary_line
    from hil.sim.realtime import RealTimeScheduler
    err = io.StringIO()
    observer = _events_printer(None, 0, err=err)
    station, _ = build_station(0, RealTimeScheduler(), config=MacConfig(checksum=True),
                               observer=observer)
    t = 0
    for k in range(4):                                     # heartbeats without crc()
        data = Frame(dst=7, src=1, num=k, type=3, content=b"").encode()
        station.uart.receive(data, t, 16640)
        t += 20 * 16640 + 200_000
    assert station.bad_checksum == station.frames_heard >= 3, (station.bad_checksum,
                                                               station.frames_heard)
    assert err.getvalue().count("\n") == 1
    assert "frames heard all failed the checksum" in err.getvalue()
    assert f"bad frames 0 (checksum failed {station.bad_checksum})" in summary_line(station)


def test_frames_failing_the_tag_are_said_once_when_every_one_did():
    """A child with ``--auth-key`` on a ring under another key sat in LISTEN; only its
    closing line's ``refused 183 (forged 183 ...)`` hinted why. Once every frame heard (three
    or more) failed the tag, the station says so in one line, as with the checksum."""
    import io
    from firmware_model.radio import auth
    from firmware_model.radio.mac import MacConfig
    from firmware_model.station import build_station
    from hil.bench.runner import _events_printer
    from hil.sim.realtime import RealTimeScheduler
    ours = auth.RingKey(bytes(range(16)))
    theirs = auth.RingKey(bytes(range(1, 17)))
    err = io.StringIO()
    observer = _events_printer(None, 2, err=err)
    station, _ = build_station(2, RealTimeScheduler(), config=MacConfig(auth=ours),
                               observer=observer)
    t = 0
    for k in range(5):                                     # heartbeats under another key
        data = auth.seal(theirs, 7, 1, k, 3, b"", k).encode()
        station.uart.receive(data, t, 16640)
        t += 40 * 16640 + 200_000
    assert station.refused.get("forged") == station.frames_heard >= 3, (station.refused,
                                                                       station.frames_heard)
    assert err.getvalue().count("\n") == 1, err.getvalue()
    assert "frames heard all failed the authentication tag" in err.getvalue()
    # a ring whose frames pass the tag is not told so, whatever else it refuses
    err2 = io.StringIO()
    station, _ = build_station(2, RealTimeScheduler(), config=MacConfig(auth=ours),
                               observer=_events_printer(None, 2, err=err2))
    t = 0
    for k in range(5):
        station.uart.receive(auth.seal(ours, 7, 1, k, 3, b"", k + 1).encode(), t, 16640)
        t += 40 * 16640 + 200_000
    assert "authentication tag" not in err2.getvalue()
