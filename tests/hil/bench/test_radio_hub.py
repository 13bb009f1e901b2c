"""The pty radio hub (hil/bench/radio_hub.py): real ptys, the simulator's Air, wall-clock pacing.

Timing bounds are generous (a loaded 2-core machine wakes threads late) but one-sided bounds
that physics guarantees are exact: no byte can arrive before its stop bit has ended."""
from __future__ import annotations

import fcntl
import os
import select
import shutil
import signal
import subprocess
import struct
import sys
import termios
import threading
import time

import pytest

from firmware_model.radio.frame import Frame
from hil.bench.hub_parts import check_args, parse_drop
from hil.bench.radio_hub import RadioHub
from hil.cli.hub import run_hub_cli, summary_line

serial = pytest.importorskip("serial")

BYTE_S = 10 / 9600          # 1.0417 ms: one 8N1 byte at 9600
FRAME = Frame(dst=7, src=0, num=12, type=3, content=b"movex(10)moveto(1.5,-2,0)").encode()


@pytest.fixture
def hubs():
    made: list[RadioHub] = []
    fds: list[int] = []

    def make(*args, **kw) -> RadioHub:
        h = RadioHub(*args, **kw)
        made.append(h)
        return h

    make.fds = fds
    yield make
    for fd in fds:
        try:
            os.close(fd)
        except OSError:
            pass
    for h in made:
        h.close()


def open_node(hubs, path: str) -> int:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    hubs.fds.append(fd)
    return fd


def read_for(fd: int, seconds: float) -> bytes:
    """Everything that arrives on ``fd`` within ``seconds``."""
    out = bytearray()
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        r, _, _ = select.select([fd], [], [], left)
        if r:
            try:
                out += os.read(fd, 65536)
            except BlockingIOError:
                pass
    return bytes(out)


def read_n(fd: int, n: int, timeout: float) -> tuple[bytes, list[float]]:
    """Read until ``n`` bytes came; the monotonic time each chunk was seen."""
    out = bytearray()
    times: list[float] = []
    end = time.monotonic() + timeout
    while len(out) < n and (left := end - time.monotonic()) > 0:
        r, _, _ = select.select([fd], [], [], left)
        if r:
            try:
                chunk = os.read(fd, n - len(out))
            except BlockingIOError:
                continue
            t = time.monotonic()
            out += chunk
            times += [t] * len(chunk)
    return bytes(out), times


def test_frame_reaches_every_other_node_intact_and_not_the_sender(hubs):
    hub = hubs(3).start()
    fds = [open_node(hubs, p) for p in hub.paths]
    os.write(fds[0], FRAME)
    got1, _ = read_n(fds[1], len(FRAME), 3.0)
    got2, _ = read_n(fds[2], len(FRAME), 3.0)
    assert got1 == FRAME
    assert got2 == FRAME
    assert read_for(fds[0], 0.1) == b""          # a node never hears its own bytes
    assert read_for(fds[1], 0.05) == b""         # and nothing else arrives
    st = hub.stats()
    assert st["transmissions"] >= 1 and st["collisions"] == 0
    assert st["per_node"][0]["bytes_in"] == len(FRAME)
    assert st["per_node"][0]["bytes_out"] == 0
    assert [n["bytes_out"] for n in st["per_node"][1:]] == [len(FRAME)] * 2


@pytest.mark.timing  # the hub's threads must run when they wake (README, "Tests")
def test_bytes_are_paced_at_the_air_byte_time(hubs):
    hub = hubs(2).start()
    tx, rx = (open_node(hubs, p) for p in hub.paths)
    time.sleep(0.05)
    data = bytes(range(48))
    t_write = time.monotonic()
    os.write(tx, data)
    got, times = read_n(rx, 48, 5.0)
    assert got == data
    first, last = times[0] - t_write, times[-1] - t_write
    # a byte is written to the pty only once its stop bit has ended on the hub's wall clock
    assert first >= BYTE_S
    assert first < 0.25, f"first byte {first * 1e3:.1f} ms after the write"
    assert last >= 48 * BYTE_S                    # 50 ms: never faster than the air
    assert last - first >= 40 * BYTE_S            # spread out, not one burst at the end
    assert last < 1.0, f"48 bytes took {last * 1e3:.0f} ms"


def test_write_while_on_air_continues_the_same_burst(hubs):
    hub = hubs(2).start()
    tx, rx = (open_node(hubs, p) for p in hub.paths)
    a, b = b"A" * 60, b"B" * 60
    t_write = time.monotonic()
    os.write(tx, a)
    time.sleep(0.02)                              # the first burst is still on air (62 ms)
    os.write(tx, b)
    got, times = read_n(rx, 120, 5.0)
    assert got == a + b                           # no self-collision
    assert times[-1] - t_write >= 120 * BYTE_S    # back to back, after the first burst
    assert hub.stats()["collisions"] == 0


def _waiting(fd: int) -> int:
    """Bytes waiting to be read on ``fd`` (FIONREAD)."""
    return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]


class _Starts:
    """A capture sink (``RadioHub.capture``) noting when each node's transmission began on
    the hub's air, in byte times."""

    tsresol = 9
    epoch_units = 0

    def __init__(self, byte_ticks: int) -> None:
        self.bt = byte_ticks
        self.start: dict[object, int] = {}

    def follow(self, clock):              # PcapWriter's: stamps stay ticks here
        pass

    def radio(self, key, tick, data, comment=None):
        self.start.setdefault(key, (tick - len(data) * self.bt) // self.bt)


def _clean_run(got: bytes, base: int) -> int:
    """The longest run of ``got`` that is a piece of the alphabet from ``base`` (A-Z or a-z
    in order, wrapping): a stretch of one frame heard clean."""
    best = run = 0
    prev = None
    for x in got:
        if base <= x < base + 26:
            run = run + 1 if prev is not None and x - base == (prev - base + 1) % 26 else 1
            prev = x
        else:
            run, prev = 0, None
        best = max(best, run)
    return best


@pytest.mark.timing  # the hub's threads must run when they wake (README, "Tests")
def test_two_nodes_at_once_collide_into_garbage(hubs):
    hub = hubs(3)
    fds = [open_node(hubs, p) for p in hub.paths]
    n = 1200                                      # 1.25 s on air each: they overlap even
    a = bytes(0x41 + i % 26 for i in range(n))    # when a loaded machine puts them on air
    b = bytes(0x61 + i % 26 for i in range(n))    # 380 ms apart (seen under a CI run)
    # Both are written before the hub starts, and it starts only once both masters hold all
    # the bytes (FIONREAD), so it reads them in one pass. Even so, twice in 20x loops on a
    # loaded machine the hub put the second node's bytes on air 100+ ms after the first's
    # (the reader thread posts each node's bytes separately to the air's thread). What the
    # test checks is the air's physics, so it takes the two start times from the hub itself:
    # clean bytes only while one transmitter was alone, garbage while both were on.
    starts = _Starts(hub.byte_ticks)
    hub.capture(starts)
    os.write(fds[0], a)
    os.write(fds[1], b)
    deadline = time.monotonic() + 10.0
    while min(_waiting(m) for m in hub.masters[:2]) < len(a):
        assert time.monotonic() < deadline, "the written bytes never reached the hub's ptys"
        time.sleep(0.01)
    hub.start()
    got = read_for(fds[2], 3.5)
    lead = abs(starts.start[0] - starts.start[1])     # bytes the first one was alone
    assert lead <= n - 250, f"the hub started the two writes {lead} byte times apart"
    assert len(got) >= 0.75 * n                   # garbage at the byte rate while overlapped
    assert len(got) <= 2 * n + 50
    assert _clean_run(got, 0x41) <= lead + 3 and _clean_run(got, 0x61) <= lead + 3, \
        (lead, got)
    # random bytes, not either frame, while both were on air
    both = got[lead + 3:n - 3] if lead else got[3:-3]
    assert len(both) >= 140 and _clean_run(both, 0x41) <= 4 and _clean_run(both, 0x61) <= 4
    # a transmitter never hears its own bytes (it is deaf while they are on air)
    assert a[-100:] not in read_for(fds[0], 0.05)
    st = hub.stats()
    assert st["collisions"] == 1
    assert st["per_node"][2]["bytes_out"] == len(got)


class _Bursts:
    """A capture sink (``RadioHub.capture``): every burst on the hub's air as (node or
    "foreign", first tick, end tick), in the air's own ticks."""

    tsresol = 9
    epoch_units = 0

    def __init__(self, byte_ticks: int) -> None:
        self.bt = byte_ticks
        self.packets: list[tuple[object, int, int]] = []

    def follow(self, clock):
        pass

    def radio(self, key, tick, data, comment=None):
        self.packets.append((key, tick - len(data) * self.bt, tick))


def test_a_transmitter_is_deaf_on_the_air_clock_until_its_rx_ready_delay_after_its_burst(hubs):
    """A PTR2000 hears nothing while TXEN is high and for its RX-ready delay after it falls
    (3 ms, 48,000 ticks: the nRF401 data sheet's TX->RX switch time, not the protocol's 5 ms
    Ttrans guard). A pty has no TXEN line, so the hub deafens a node while its burst is on air
    and for that delay after the burst ends there, on the air's own clock: a bench process,
    whose bytes reach the air late and which dates its own End earlier, never hears the
    garbage of a collision with its own frame (issue 40: it took it for its successor's
    broken frame). Node 0 sends 400 bytes; a foreign transmitter collides with them and goes
    on after them. Node 0 hears the garbage only from its burst's end + 3 ms to the end of
    the collision, to the byte (with Ttrans, about 2 bytes fewer); node 1, listening
    throughout, hears the collision from its start."""
    from firmware_model.timing import PTR2000_RX_READY_TICKS, TTRANS_TICKS
    from hil.sim.faults import parse_fault
    hub = hubs(2, seed=3, faults=[parse_fault("foreign@0.25:400")])
    bursts = _Bursts(hub.byte_ticks)
    hub.capture(bursts)
    fds = [open_node(hubs, p) for p in hub.paths]
    mine = bytes(0x41 + i % 26 for i in range(400))
    os.write(fds[0], mine)
    deadline = time.monotonic() + 10.0
    while _waiting(hub.masters[0]) < len(mine):  # one read, one burst, once the hub runs
        assert time.monotonic() < deadline, "the written bytes never reached the hub's pty"
        time.sleep(0.01)
    hub.start()
    got0 = read_for(fds[0], 2.0)
    got1 = read_for(fds[1], 0.2)
    bt = hub.byte_ticks
    (_, s0, e0), = [p for p in bursts.packets if p[0] == 0]
    (_, fs, fe), = [p for p in bursts.packets if p[0] == "foreign"]
    assert s0 < fs < e0 - 50 * bt and fe > e0 + TTRANS_TICKS + 50 * bt, \
        f"the hub put node 0's bytes on air too late to collide as planned: {bursts.packets}"
    assert _clean_run(got0, 0x41) <= 4            # never its own bytes (random: a few)
    assert len(got0) == (fe - e0 - PTR2000_RX_READY_TICKS) // bt   # deaf until e0 + 3 ms
    assert len(got0) > (fe - e0 - TTRANS_TICKS) // bt
    assert len(got1) >= (fe - s0) // bt - 2       # node 1 heard it all, garbage from fs
    assert hub.stats()["collisions"] == 1


def test_ber_corrupts_bytes_seeded(hubs):
    data = bytes(range(200))
    results = []
    for seed in (7, 7, 8):
        hub = hubs(2, ber=0.5, seed=seed).start()
        tx, rx = (open_node(hubs, p) for p in hub.paths)
        os.write(tx, data)
        got, _ = read_n(rx, 200, 5.0)
        assert len(got) == 200
        bad = sum(1 for x, y in zip(got, data) if x != y)
        assert 60 <= bad <= 140
        # one bit flipped per corrupted byte
        assert all(bin(x ^ y).count("1") == 1 for x, y in zip(got, data) if x != y)
        results.append(got)
        hub.close()
    assert results[0] == results[1]               # same seed, same corruption
    assert results[0] != results[2]


def test_noise_fills_an_idle_link_at_the_byte_rate(hubs):
    hub = hubs(2, noise=True, seed=3)
    t0 = time.monotonic()
    hub.start()
    fd = open_node(hubs, hub.paths[1])
    got = read_for(fd, 0.4)
    elapsed = time.monotonic() - t0
    assert len(got) >= 100                        # ~380 expected
    assert len(got) <= elapsed / BYTE_S + 2       # never faster than the air
    assert len(set(got)) > 50
    st = hub.stats()
    assert st["per_node"][1]["noise"] >= len(got)
    assert st["transmissions"] == 0


def test_dropped_link_hears_nothing_and_its_writes_vanish(hubs):
    hub = hubs(3, drops=[(1, 0.0, 1.5)])
    t0 = time.monotonic()
    hub.start()
    fds = [open_node(hubs, p) for p in hub.paths]
    os.write(fds[0], b"to-all-but-1")
    os.write(fds[1], b"from-1-lost")
    time.sleep(0.3)
    assert time.monotonic() - t0 < 1.4, "machine too slow for the drop window"
    assert read_for(fds[1], 0.05) == b""          # down: hears nothing
    heard2 = read_for(fds[2], 0.05)
    assert heard2 == b"to-all-but-1"              # node 1's bytes never went on air
    assert read_for(fds[0], 0.05) == b""
    time.sleep(max(0.0, 1.6 - (time.monotonic() - t0)))
    os.write(fds[0], b"after")
    got, _ = read_n(fds[1], 5, 3.0)
    assert got == b"after"                        # the link is back
    st = hub.stats()
    assert st["per_node"][1]["lost"] == len(b"from-1-lost")
    assert st["per_node"][1]["transmissions"] == 0


def test_links_created_and_removed(hubs, tmp_path):
    d = tmp_path / "radio"
    hub = hubs(3, link_dir=str(d))
    for i, path in enumerate(hub.paths):
        link = d / f"node{i}"
        assert link.is_symlink()
        assert os.readlink(link) == path
    assert hub.links == [str(d / f"node{i}") for i in range(3)]
    hub.start()
    fd0, fd1 = open_node(hubs, str(d / "node0")), open_node(hubs, str(d / "node1"))
    os.write(fd0, b"hello")
    assert read_n(fd1, 5, 3.0)[0] == b"hello"
    hub.close()
    assert not d.exists()                         # the hub made the dir: it removes it

    keep = tmp_path / "keep"
    keep.mkdir()
    (keep / "node0").symlink_to("/nonexistent")   # a stale link from a crashed hub
    with RadioHub(1, link_dir=str(keep)) as h:
        assert os.readlink(keep / "node0") == h.paths[0]
    assert keep.is_dir() and list(keep.iterdir()) == []


def test_a_second_hub_on_the_same_link_dir_is_refused_and_the_first_keeps_its_links(
        hubs, tmp_path):
    """A second ``rprs radio-hub --link-dir DIR`` (another terminal) took the running hub's
    links as stale ones and replaced them: robots started after it went to the second air,
    those before stayed on the first, and when the second hub stopped it removed the links
    of the first, still running. Now the second is refused in one line; the first hub's
    links stay, and a hub that is gone (its links stale) is still replaced."""
    d = tmp_path / "air"
    first = hubs(2, link_dir=str(d))
    with pytest.raises(ValueError, match="another radio hub is using it"):
        RadioHub(2, link_dir=str(d))
    assert [os.readlink(d / f"node{i}") for i in range(2)] == first.paths
    r = subprocess.run([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                        "--link-dir", str(d)], capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "another radio hub is using it" in r.stderr
    assert [os.readlink(d / f"node{i}") for i in range(2)] == first.paths
    first.close()
    assert not d.exists()
    (tmp_path / "kept").mkdir()
    (tmp_path / "kept" / "node0").symlink_to(first.paths[0])     # left by a killed hub
    with RadioHub(1, link_dir=str(tmp_path / "kept")) as again:
        assert os.readlink(tmp_path / "kept" / "node0") == again.paths[0]


def test_a_bad_link_dir_is_refused_in_one_line_and_nothing_is_left(tmp_path):
    """A --link-dir under a missing directory, under a file, that is a file, or holding a
    regular file named nodeN is refused with a ValueError (the CLI's one line, status 2);
    the hub makes no parents and leaves no pty or link behind."""
    (tmp_path / "file").write_text("x")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "node1").write_text("keep me")
    cases = {tmp_path / "missing" / "air": "parent directory .* does not exist",
             tmp_path / "file" / "air": "Not a directory",
             tmp_path / "file": r"not a directory \(a file is there\)",    # said "File exists"
             tmp_path / "full": "node1 exists and is not a symlink"}
    before = len(os.listdir("/proc/self/fd"))
    for d, why in cases.items():
        with pytest.raises(ValueError, match=why):
            RadioHub(2, link_dir=str(d))
    assert not (tmp_path / "missing").exists()
    assert sorted(p.name for p in (tmp_path / "full").iterdir()) == ["node1"]
    assert (tmp_path / "full" / "node1").read_text() == "keep me"
    assert len(os.listdir("/proc/self/fd")) == before        # every pty closed
    r = subprocess.run([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                        "--link-dir", str(tmp_path / "missing" / "air")],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


def test_slave_is_raw_no_echo_no_translation(hubs):
    hub = hubs(2).start()
    special = b"\x0a\x0d\x03\x11\x13\x04\x1a\x7f\x00\xff\x0d\x0a"
    s0 = serial.Serial(hub.paths[0], timeout=0.2)
    s1 = serial.Serial(hub.paths[1], timeout=3.0)
    try:
        s0.write(special)
        s0.flush()
        assert s1.read(len(special)) == special
        assert s0.read(64) == b""                 # no echo, no own bytes
    finally:
        s0.close()
        s1.close()
    # raw from the start too, for a program that does not set the line itself
    fd0, fd1 = (open_node(hubs, p) for p in hub.paths)
    os.write(fd0, special)
    assert read_n(fd1, len(special), 3.0)[0] == special
    assert read_for(fd0, 0.1) == b""


SOCAT = shutil.which("socat")


@pytest.mark.skipif(SOCAT is None, reason="socat not installed (Debian package socat)")
def test_socat_a_client_nobody_here_wrote_sends_and_receives_frames_on_the_hub(hubs):
    """docs/guarantees.md says findings were made with socat on the hub: socat, which sets its
    own line (``rawer``), is a node like any other. A frame (Header 0F 0A 05, End 17 19) and
    the bytes a cooked line would eat go from socat on node 0 to a plain reader on node 1, and
    a frame written on node 1 comes out of socat's stdout on node 0 unchanged."""
    hub = hubs(2).start()
    payload = FRAME + b"\x0a\x0d\x03\x11\x13\x04\x1a\x7f\x00\xff"
    fd1 = open_node(hubs, hub.paths[1])
    sock = subprocess.Popen([SOCAT, "-b", "65536", "-", f"OPEN:{hub.paths[0]},rawer"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        time.sleep(0.3)                           # socat has opened and set up its node
        sock.stdin.write(payload)
        sock.stdin.flush()
        assert read_n(fd1, len(payload), 5.0)[0] == payload
        time.sleep(0.02)    # node 0 is deaf until 3 ms after its burst (docs/radio-hub.md)
        os.write(fd1, FRAME)                      # and back: socat prints what its node hears
        got = bytearray()
        end = time.monotonic() + 5.0
        while len(got) < len(FRAME) and time.monotonic() < end:
            r, _, _ = select.select([sock.stdout], [], [], end - time.monotonic())
            if r:
                got += os.read(sock.stdout.fileno(), 65536)
        assert bytes(got) == FRAME                # not its own bytes echoed, not translated
        assert read_for(fd1, 0.2) == b""          # nothing more came to node 1
    finally:
        sock.stdin.close()
        try:
            sock.wait(timeout=5)
        except subprocess.TimeoutExpired:
            sock.kill()
            sock.wait(timeout=5)
        err = sock.stderr.read()
        sock.stdout.close()
        sock.stderr.close()
    assert sock.returncode == 0, err


def _cooked(fd: int) -> None:
    """What ``stty sane`` does to a terminal, done by an outside client on its node: echo,
    line editing, signals, CR/LF translation and XON/XOFF on."""
    attrs = termios.tcgetattr(fd)
    attrs[0] |= termios.ICRNL | termios.IXON
    attrs[1] |= termios.OPOST | termios.ONLCR
    attrs[3] |= termios.ECHO | termios.ECHOE | termios.ECHOK | termios.ICANON | termios.ISIG \
        | termios.IEXTEN
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


def test_a_client_that_turns_echo_on_does_not_echo_the_air_back(hubs):
    """The hub set its slaves raw once, when it made them. A program that opened a node and
    turned echo on (``stty sane``, a terminal program, a script's ``os.open`` + termios) made
    the pty echo every byte the air brought it back to the hub, which put it on air as that
    node's own transmission: the sender heard its frame come back (a forgery of itself) and
    the air carried it twice. The hub now keeps its nodes raw: it sets raw mode again before
    it writes to a node, and once every poll interval, and counts each time it had to."""
    hub = hubs(2).start()
    a = serial.Serial(hub.paths[0], timeout=0.3)  # plain pyserial: raw, as it sets itself
    try:
        fd = open_node(hubs, hub.paths[1])        # an outside client, cooked
        _cooked(fd)
        a.write(b"hel\rlo\n")
        a.flush()
        got = read_n(fd, 7, 3.0)[0]
        assert got == b"hel\rlo\n"                # no CR -> LF, no line discipline
        assert a.read(64) == b""                  # nothing echoed back on air
        assert not termios.tcgetattr(fd)[3] & (termios.ECHO | termios.ICANON)
        n0, n1 = hub.stats()["per_node"][:2]
        assert n1["bytes_in"] == 0 and n1["raw_restored"] >= 1
        assert n0["raw_restored"] == 0            # pyserial's own settings are raw enough
        # turned cooked again while the air is quiet: raw again within a poll interval or so
        _cooked(fd)
        deadline = time.monotonic() + 5.0
        while termios.tcgetattr(fd)[3] & termios.ECHO and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not termios.tcgetattr(fd)[3] & termios.ECHO
        os.write(fd, b"x\n")                      # no LF -> CR LF on its way out
        assert a.read(3) == b"x\n"
        assert "raw mode restored" in summary_line(hub.stats())
    finally:
        a.close()


def test_slow_reader_is_dropped_and_the_hub_never_blocks(hubs):
    hub = hubs(2, baud=1_000_000).start()         # 10 us a byte: fill a pty quickly
    data = bytes(i % 251 for i in range(60_000))
    fd1 = open_node(hubs, hub.paths[1])           # node 1 has it open, and does not read
    fd0 = os.open(hub.paths[0], os.O_RDWR | os.O_NOCTTY)   # blocking writer
    hubs.fds.append(fd0)
    w = threading.Thread(target=os.write, args=(fd0, data), daemon=True)
    w.start()
    w.join(20.0)
    assert not w.is_alive(), "writer blocked: the hub stopped taking bytes"
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline:
        n1 = hub.stats()["per_node"][1]
        if n1["bytes_out"] + n1["dropped"] >= len(data):
            break
        time.sleep(0.05)
    n1 = hub.stats()["per_node"][1]
    assert n1["bytes_out"] + n1["dropped"] == len(data)
    assert n1["dropped"] > 0 and n1["not_open"] == 0
    assert 0 < n1["bytes_out"] < len(data)
    # node 1 finally reads: the bytes kept are the oldest ones, in order
    kept = read_for(fd1, 0.2)
    assert len(kept) == n1["bytes_out"]
    assert kept[:1000] == data[:1000]


def test_a_node_no_program_has_open_is_not_a_slow_reader(hubs):
    """Bytes for a node whose pty no program had open were written into that pty anyway: up to
    its buffer (kept for whoever opened it later, stale), then counted with a slow reader's in
    "dropped (slow reader)", so that a hub with an unused node reported thousands of bytes
    dropped while every robot read all it was sent. The hub now writes nothing to a node
    nobody has open and counts those bytes apart, as ``not_open``; a program that opens the
    node hears the air from then on, and closing it again makes it a node nobody has open."""
    hub = hubs(3, baud=96_000).start()            # 0.1 ms a byte: 6000 bytes in 0.6 s
    data = bytes(i % 251 for i in range(6000))
    fd0 = os.open(hub.paths[0], os.O_RDWR | os.O_NOCTTY)   # blocking writer
    hubs.fds.append(fd0)
    fd1 = open_node(hubs, hub.paths[1])           # node 1 reads everything; node 2: nobody
    w = threading.Thread(target=os.write, args=(fd0, data), daemon=True)
    w.start()
    got1 = read_n(fd1, len(data), 30.0)[0]
    w.join(5.0)
    assert got1 == data
    deadline = time.monotonic() + 10.0
    while hub.stats()["per_node"][2]["not_open"] < len(data) and time.monotonic() < deadline:
        time.sleep(0.02)
    st = hub.stats()
    n2 = st["per_node"][2]
    assert n2["not_open"] == len(data) and n2["bytes_out"] == 0 and n2["dropped"] == 0
    assert st["dropped"] == 0 and st["not_open"] == len(data)
    line = summary_line(st)
    assert "0 dropped (slow reader)" in line, line
    assert f"{len(data)} not delivered (node not open)" in line, line
    # opened now: nothing stale waits in its pty, and it hears what goes on air from now on
    fd2 = open_node(hubs, hub.paths[2])
    assert read_for(fd2, 0.1) == b""
    os.write(fd0, b"now")
    assert read_n(fd2, 3, 5.0)[0] == b"now"
    assert read_n(fd1, 3, 5.0)[0] == b"now"
    # closed again: nobody has it open, and its bytes are counted so again
    hubs.fds.remove(fd2)
    os.close(fd2)
    os.write(fd0, b"later")
    assert read_n(fd1, 5, 5.0)[0] == b"later"
    time.sleep(0.05)
    n2 = hub.stats()["per_node"][2]
    assert (n2["bytes_out"], n2["dropped"], n2["not_open"]) == (3, 0, len(data) + 5)


def test_stop_leaves_no_threads_and_closes_fds(hubs, tmp_path):
    before = set(threading.enumerate())
    hub = RadioHub(2, noise=True, link_dir=str(tmp_path / "l"))
    masters = list(hub.masters)
    hub.start()
    time.sleep(0.05)
    assert len(set(threading.enumerate()) - before) == 2
    hub.stop()
    assert set(threading.enumerate()) - before == set()
    hub.close()
    hub.close()                                   # idempotent
    for fd in masters:
        with pytest.raises(OSError):
            os.fstat(fd)
    assert not (tmp_path / "l").exists()


def test_run_forever_in_the_calling_thread(hubs):
    hub = hubs(2)
    t = threading.Thread(target=hub.run_forever)
    t.start()
    fd0, fd1 = (open_node(hubs, p) for p in hub.paths)
    os.write(fd0, b"xyz")
    assert read_n(fd1, 3, 3.0)[0] == b"xyz"
    hub.stop()
    t.join(5.0)
    assert not t.is_alive()


def _threads_of(hub) -> list[threading.Thread]:
    return [t for t in hub._threads if t.is_alive()]


def test_a_failing_air_thread_stops_the_hub_and_says_why(hubs):
    """A byte of 0 ticks (``--baud 1e9``, refused by the parser now) raised ZeroDivisionError
    in the air thread: the thread died, the reader and the ptys lived on, and the hub looked
    alive. Any exception in the air thread now stops the whole hub, keeps the exception and
    says in one line what and where."""
    hub = hubs(2)
    hub.byte_ticks = 0                        # what round(1.6e8 / 1e9) gave
    hub.start()
    fd0, fd1 = (open_node(hubs, p) for p in hub.paths)
    os.write(fd0, b"x")
    assert hub.wait(10.0)
    assert isinstance(hub.error, ZeroDivisionError)
    line = hub.failure()
    assert "\n" not in line and line.startswith("the radio hub stopped: its air thread failed")
    assert "ZeroDivisionError" in line and "firmware_model/mcu/uart.py" in line
    assert "rates_agree" in line
    hub.stop()
    assert not _threads_of(hub)
    assert hub.stats()["bytes_in"] == 1
    assert read_for(fd1, 0.1) == b""


def test_a_failing_reader_thread_stops_the_hub(hubs, monkeypatch):
    """The reader returned silently on an unexpected OSError, leaving the air running with
    nobody reading the ptys. Now that stops the hub too."""
    import errno as errno_

    from hil.bench import radio_hub

    def bad_poll(*args):
        raise OSError(errno_.EBADF, "Bad file descriptor")

    monkeypatch.setattr(radio_hub, "_poll", bad_poll)
    hub = hubs(2).start()
    assert hub.wait(10.0)
    assert isinstance(hub.error, OSError)
    assert "its reader thread failed with OSError" in hub.failure()
    hub.stop()
    assert not _threads_of(hub)


def test_run_forever_raises_what_stopped_the_hub(hubs):
    from hil.bench.radio_hub import HubError
    hub = hubs(2)
    hub.byte_ticks = 0
    raised: list[BaseException] = []

    def run():
        try:
            hub.run_forever()
        except BaseException as exc:           # noqa: BLE001 - the test looks at it
            raised.append(exc)

    t = threading.Thread(target=run)
    t.start()
    while not hub.paths or hub.sched is None:
        time.sleep(0.01)
    fd0 = open_node(hubs, hub.paths[0])
    os.write(fd0, b"x")
    t.join(10.0)
    assert not t.is_alive()
    assert len(raised) == 1 and isinstance(raised[0], HubError)
    assert isinstance(raised[0].__cause__, ZeroDivisionError)
    assert str(raised[0]) == hub.failure()


def test_cli_hub_whose_air_thread_fails_exits_by_itself_in_one_line():
    """``rprs radio-hub --baud 1e9`` and a byte written: the air thread died of
    ZeroDivisionError, the hub ran on with a dead channel and exited 0 on Ctrl-C. With the
    same failure forced (the parser now refuses that baud), the hub stops at once, prints its
    summary and one line ``rprs: error: ...``, status 2, no traceback."""
    code = ("import sys; import hil.bench.radio_hub as h; h.byte_ticks_for = lambda baud: 0; "
            "from hil.cli import main; sys.exit(main(['radio-hub', '--nodes', '2']))")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    fd = -1
    try:
        paths = [p.stdout.readline().split()[2] for _ in range(2)]
        fd = os.open(paths[0], os.O_RDWR | os.O_NOCTTY)
        os.write(fd, b"x")
        out, err = p.communicate(timeout=30)   # no signal: it ends by itself
    finally:
        if fd >= 0:
            os.close(fd)
        _kill(p)
    assert p.returncode == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("rprs: error: the radio hub stopped: its air thread failed with "
                          "ZeroDivisionError")
    assert "rates_agree" in err
    assert out.strip().splitlines()[-1].startswith("radio-hub: ")


@pytest.mark.parametrize("run", [
    lambda s: s.run_forever(), lambda s: s.run_for(1e300), lambda s: s.run_for(1e303),
    lambda s: s.run_until(10 ** 400),
], ids=["run_forever", "run_for-1e300", "run_for-1e303", "run_until-10**400"])
def test_the_scheduler_waits_for_a_far_event_or_end_without_overflow(run):
    """An event or an end beyond ``threading.TIMEOUT_MAX`` (a hub's drop at 1e300 s, a robot's
    ``--duration 1e300``) killed the scheduler's loop with "OverflowError: timestamp out of
    range for platform time_t" at its first wait. It waits in slices now and still runs what
    other threads post, and stops when told."""
    from firmware_model.timing import s_to_ticks
    from hil.sim.realtime import RealTimeScheduler
    sched = RealTimeScheduler()
    sched.at(s_to_ticks(1e300), lambda: None)
    failed: list[BaseException] = []
    ran = threading.Event()

    def loop():
        try:
            run(sched)
        except BaseException as exc:          # noqa: BLE001 - the test reports it
            failed.append(exc)

    t = threading.Thread(target=loop)
    t.start()
    sched.post(ran.set)
    assert ran.wait(10.0), failed
    sched.stop()
    t.join(10.0)
    assert not t.is_alive() and not failed


@pytest.mark.parametrize("kw, msg", [
    (dict(nodes=0), "nodes"), (dict(nodes=8), "nodes"), (dict(baud=0), "baud"),
    (dict(baud=-9600), "baud"), (dict(ber=1.0), "error rate"), (dict(ber=-0.1), "error rate"),
    (dict(drops=[(3, 0, 1)]), "drop node"), (dict(drops=[(0, 2, 1)]), "window"),
    (dict(baud=1e9), "baud"), (dict(baud=16_000_001), "baud"), (dict(baud=0.5), "baud"),
    (dict(baud=1e-300), "baud"), (dict(baud=float("nan")), "baud"),
    (dict(drops=[(0, 0, 1e300)]), "window"), (dict(drops=[(0, 0, 10_000_001)]), "window"),
])
def test_bad_arguments(kw, msg):
    args = dict(nodes=2, baud=9600, ber=0.0, drops=())
    args.update(kw)
    with pytest.raises(ValueError, match=msg):
        check_args(**args)
    with pytest.raises(ValueError, match=msg):
        run_hub_cli(**args)
    with pytest.raises(ValueError, match=msg):
        RadioHub(**args)


def test_parse_drop():
    assert parse_drop("2@5-8.5") == (2, 5.0, 8.5)
    assert parse_drop("1@0-10000000") == (1, 0.0, 1e7)
    for bad in ("2@5", "x@1-2", "2-5", "9@1-2", "1@3-2", "1@0-1e300", "1@0-10000001",
                "1@0-inf", "1@nan-2"):
        with pytest.raises(ValueError):
            parse_drop(bad)


@pytest.mark.parametrize("args, needle", [
    (["--baud", "1e9"], "baud must be a number from 1 to 16000000"),
    (["--baud", "3.3e8"], "baud must be a number from 1 to 16000000"),
    (["--baud", "1e-300"], "baud must be a number from 1 to 16000000"),
    (["--baud", "0"], "baud must be a number from 1 to 16000000"),
    (["--baud", "inf"], "baud must be a number from 1 to 16000000"),
    (["--baud", "fast"], "is not a number"),
    (["--drop", "1@0-1e300"], "END <= 10000000"),
    (["--fault", "noise@0-10000001"], "at most 10000000 s"),
    (["--fault", "foreign@99999999:3"], "at most 10000000 s"),
    (["--fault", "fail:1@10000000.5"], "at most 10000000 s"),
    (["--fault", "noise@0-1" + "0" * 400], "too large to be finite"),
    # was "its parent directory /work does not exist" (the parent of the working directory)
    (["--link-dir", ""], "an empty directory name"),
    (["--link-dir", " "], "an empty directory name"),
])
def test_cli_refuses_values_the_hub_cannot_play_when_it_parses_them(capsys, args, needle):
    """``--baud 1e9`` (a byte of 0 ticks: ZeroDivisionError at the first byte), ``--baud
    1e-300`` and ``--drop 1@0-1e300`` (OverflowError in the scheduler) were accepted and killed
    the hub's air thread while the hub ran on. Now they are one line at parse time, status 2,
    before any pty is made."""
    from hil.cli import main
    assert main(["radio-hub", "--nodes", "2", *args]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("rprs: error: ") and err.count("\n") == 1
    assert needle in err and "Traceback" not in err


@pytest.mark.parametrize("baud", [16_000_000, 3.3e5])
def test_the_fastest_air_carries_bytes(hubs, baud):
    """At the fastest baud the hub accepts a byte lasts 10 ticks and reaches the other node."""
    hub = hubs(2, baud=baud).start()
    assert hub.byte_ticks == round(160_000_000 / baud) >= 10
    fd0, fd1 = (open_node(hubs, p) for p in hub.paths)
    os.write(fd0, b"xyz" * 100)
    assert read_n(fd1, 300, 5.0)[0] == b"xyz" * 100


def test_the_latest_drop_and_fault_are_accepted_and_the_hub_runs(hubs):
    """A drop window and a fault at the documented maximum (MAX_SECONDS) are scheduled
    without overflow, and the air goes on carrying bytes."""
    from hil.bench.hub_parts import MAX_SECONDS
    from hil.sim.faults import parse_fault
    hub = hubs(2, drops=[(1, MAX_SECONDS - 1, MAX_SECONDS)],
               faults=[parse_fault(f"noise@{MAX_SECONDS - 1}-{MAX_SECONDS}"),
                       parse_fault(f"foreign@{MAX_SECONDS}:3")]).start()
    fd0, fd1 = (open_node(hubs, p) for p in hub.paths)
    os.write(fd0, b"xyz")
    assert read_n(fd1, 3, 5.0)[0] == b"xyz"
    time.sleep(0.02)            # node 0's radio hears again 3 ms after its burst ends
    os.write(fd1, b"abc")
    assert read_n(fd0, 3, 5.0)[0] == b"abc"


def _kill(p: subprocess.Popen) -> None:
    if p.poll() is None:
        p.kill()
        p.wait()


def _stopped_with_summary(p: subprocess.Popen, sig: int) -> str:
    """Send ``sig`` to the hub process ``p``: it must end with status 0 and its summary last
    on stdout, which is returned."""
    p.send_signal(sig)
    out, err = p.communicate(timeout=10)
    assert p.returncode == 0, err
    assert out.strip().splitlines()[-1].startswith("radio-hub: ")
    return out


def test_cli_prints_paths_and_summary_on_signal(tmp_path):
    code = ("import sys; from hil.cli.hub import run_hub_cli; "
            f"sys.exit(run_hub_cli(2, link_dir={str(tmp_path / 'r')!r}))")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    try:
        lines = [p.stdout.readline() for _ in range(2)]
        assert lines[0].startswith("node 0: /dev/")
        assert lines[1].startswith("node 1: /dev/")
        assert str(tmp_path / "r" / "node1") in lines[1]
        path1 = lines[1].split()[2]
        fd = os.open(lines[0].split()[2], os.O_RDWR | os.O_NOCTTY)
        fd1 = os.open(path1, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            os.write(fd, b"ping")
            assert read_n(fd1, 4, 5.0)[0] == b"ping"
        finally:
            os.close(fd)
            os.close(fd1)
        out = _stopped_with_summary(p, signal.SIGTERM)
    finally:
        _kill(p)
    assert "4 bytes in" in out
    assert not (tmp_path / "r").exists()


@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="no SIGHUP on this platform")
def test_a_hub_whose_terminal_closes_removes_its_links(tmp_path):
    """Closing the terminal that runs ``rprs radio-hub`` sends it SIGHUP: it died at once
    (status 129), its links left pointing at /dev/pts/N, which the next terminal or ssh
    session is given, so that a robot started on the old link opened someone's terminal.
    It now stops as on SIGTERM: links removed, summary, status 0."""
    p = subprocess.Popen([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                          "--link-dir", str(tmp_path / "air")], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().startswith("node 0: /dev/")
        assert p.stdout.readline().startswith("node 1: /dev/")
        assert (tmp_path / "air" / "node1").is_symlink()
        _stopped_with_summary(p, signal.SIGHUP)
    finally:
        _kill(p)
    assert not (tmp_path / "air").exists()


# -- a foreign transmitter: the hub's ``foreign`` fault and ``rprs inject`` ----------------------

FOREIGN = bytes.fromhex("0f0a0530313233343536373839ff00")


def test_foreign_fault_reaches_every_node_at_its_time(hubs):
    from hil.sim.faults import foreign_bytes, parse_fault
    rand = parse_fault("foreign@0.6:20")
    hub = hubs(3, seed=7, faults=[parse_fault(f"foreign@0.3:x{FOREIGN.hex()}"), rand])
    fds = [open_node(hubs, p) for p in hub.paths]
    before = time.monotonic()
    hub.start()
    want = FOREIGN + foreign_bytes(rand, 7)
    for fd in fds:                                # no node sent them: every node hears them
        got, times = read_n(fd, len(want), 10.0)
        assert got == want
        assert times[0] - before >= 0.3 + BYTE_S  # the first stop bit ends after 0.3 s + 1 byte
        assert read_for(fd, 0.05) == b""
    st = hub.stats()
    assert st["transmissions"] == 2 and st["bytes_in"] == 0 and st["collisions"] == 0
    assert [n["bytes_out"] for n in st["per_node"]] == [len(want)] * 3


def test_cli_refuses_a_bad_foreign_fault(capsys):
    from hil.cli import main
    assert main(["radio-hub", "--fault", "foreign@1:x0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rprs: error: ") and err.count("\n") == 1 and "hex" in err


def test_inject_writes_exact_bytes_after_at_seconds(capsys):
    from hil.cli import main
    from hil.sim.faults import foreign_bytes, parse_fault
    master, slave = os.openpty()
    try:
        path = os.ttyname(slave)
        os.set_blocking(master, False)
        t0 = time.monotonic()
        assert main(["inject", "--radio", path, "--hex", "0f 0a 05 ff", "--at", "0.4"]) == 0
        got, times = read_n(master, 4, 5.0)
        assert got == b"\x0f\x0a\x05\xff" and times[0] - t0 >= 0.4
        assert "wrote 4 bytes" in capsys.readouterr().out
        assert main(["inject", "--radio", path, "--random", "33", "--seed", "4"]) == 0
        assert read_n(master, 34, 2.0)[0] == foreign_bytes(parse_fault("foreign@0:33"), 4)
    finally:
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize("args, needle", [
    (["--radio", "/nonexistent/pty", "--hex", "00"], "does not exist"),
    (["--radio", "/dev/null", "--hex", "00"], "cannot open serial port"),
    (["--radio", "/dev/null", "--hex", "0g"], "hex digits"),
    (["--radio", "/dev/null", "--hex", "abc"], "hex digits"),
    (["--radio", "/dev/null", "--random", "0"], "whole number of bytes"),
    (["--radio", "/dev/null", "--random", "x"], "invalid int"),
    (["--radio", "/dev/null", "--hex", "00", "--at", "-1"], "seconds >= 0"),
    (["--radio", "/dev/null", "--hex", "00", "--at", "1e300"], "at most 10000000 seconds"),
    (["--radio", "/dev/null", "--hex", "00", "--at", "inf"], "seconds >= 0"),
    (["--radio", "/dev/null", "--random", "65537"], "1-65536"),
    (["--radio", "/dev/null", "--hex", "00", "--random", "3"], "not allowed with"),
    (["--radio", "/dev/null"], "one of the arguments --hex --random is required"),
])
def test_inject_mistakes_are_one_line_and_status_2(capsys, args, needle):
    from hil.cli import main
    assert main(["inject", *args]) == 2
    out, err = capsys.readouterr()
    assert err.startswith("rprs: error: ") and err.count("\n") == 1
    assert needle in err and "Traceback" not in err


def test_inject_process_bad_port_is_one_line_status_2():
    r = subprocess.run([sys.executable, "-m", "hil.cli", "inject", "--radio", "/nonexistent",
                        "--hex", "00"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert r.stderr.startswith("rprs: error: serial port /nonexistent does not exist")


def test_inject_large_hex_waits_for_a_slow_port_instead_of_timing_out(capsys):
    """The port was opened with a 2 s write timeout: a payload that takes the port longer
    than 2 s to accept (beyond its ~20 KB of buffer) failed with "Write timeout" after part of
    it was written. The reader of the pty here takes 10 KB/s, so the 60000 bytes need about
    4 s; a slower reader (a busy machine) only makes it take longer, nothing is dropped."""
    import random as random_

    from hil.cli import main
    data = random_.Random(11).randbytes(60_000)
    master, slave = os.openpty()
    got = bytearray()
    stop = threading.Event()

    def slow_reader():
        while not stop.is_set() and len(got) < len(data):
            r, _, _ = select.select([master], [], [], 0.1)
            if r:
                got.extend(os.read(master, 1024))
                time.sleep(0.1)

    t = threading.Thread(target=slow_reader)
    t.start()
    try:
        code = main(["inject", "--radio", os.ttyname(slave), "--hex", data.hex()])
        out, err = capsys.readouterr()
        assert code == 0, err
        assert out.startswith(f"wrote {len(data)} bytes to ")
        t.join(60.0)
        assert bytes(got) == data
    finally:
        stop.set()
        t.join(10.0)
        os.close(master)
        os.close(slave)


def test_inject_65536_random_bytes_through_a_hub_process_all_arrive():
    """``rprs inject --random N`` failed above about 14,000 bytes into a hub at 9600 baud
    ("Write timeout", part of the data already on air) although 1-65536 is documented. At
    64000 baud (6400 bytes/s: about 10 s, four times the old 2 s timeout beyond what the pty
    and the hub's backlog buffer) every byte goes on air and reaches the other node, read
    with pyserial, in order."""
    from hil.sim.faults import foreign_bytes, parse_fault
    want = foreign_bytes(parse_fault("foreign@0:65536"), 5)
    hub = subprocess.Popen([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                            "--baud", "64000"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    rx = inj = None
    try:
        paths = [hub.stdout.readline().split()[2] for _ in range(2)]
        rx = serial.Serial(paths[1], timeout=0.5)
        inj = subprocess.Popen([sys.executable, "-m", "hil.cli", "inject", "--radio", paths[0],
                                "--random", "65536", "--seed", "5"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        got = bytearray()
        deadline = time.monotonic() + 120.0
        while len(got) < len(want) and time.monotonic() < deadline \
                and inj.poll() in (None, 0):
            got += rx.read(len(want) - len(got))
        out, err = inj.communicate(timeout=60)
        assert inj.returncode == 0, err
        assert out.startswith("wrote 65536 bytes to ")
        assert len(got) == len(want) and bytes(got) == want
        rx.timeout = 0.2
        assert rx.read(1) == b""
        hub.send_signal(signal.SIGTERM)
        hub_out, hub_err = hub.communicate(timeout=20)
    finally:
        if rx is not None:
            rx.close()
        for proc in (inj, hub):
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.wait()
    assert hub.returncode == 0, hub_err
    summary = hub_out.strip().splitlines()[-1]
    assert "65536 bytes in, 65536 bytes out" in summary and "0 dropped" in summary


def test_inject_and_foreign_fault_against_a_radio_hub_process():
    """``rprs radio-hub --fault foreign@...`` and ``rprs inject`` into one of its nodes: both
    reach the other node, and random bytes under one seed and spec are the same in both."""
    from hil.sim.faults import foreign_bytes, parse_fault
    hub = subprocess.Popen([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                            "--seed", "3", "--fault", "foreign@0.2:16"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    fd = -1

    def inject(*args):
        r = subprocess.run([sys.executable, "-m", "hil.cli", "inject", "--radio", paths[0],
                            *args], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr

    try:
        paths = [hub.stdout.readline().split()[2] for _ in range(2)]
        fd = os.open(paths[1], os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        want = foreign_bytes(parse_fault("foreign@0.2:16"), 3)
        assert read_n(fd, 16, 20.0)[0] == want                     # the hub's own fault
        inject("--hex", FOREIGN.hex())
        assert read_n(fd, len(FOREIGN), 20.0)[0] == FOREIGN        # as node 0's program
        inject("--random", "16", "--seed", "3", "--at", "0.2")
        assert read_n(fd, 16, 20.0)[0] == want                     # same spec, same seed
        assert read_for(fd, 0.1) == b""
        hub.send_signal(signal.SIGTERM)
        out, err = hub.communicate(timeout=20)
    finally:
        if fd >= 0:
            os.close(fd)
        if hub.poll() is None:
            hub.kill()
            hub.wait()
    assert hub.returncode == 0, err
    summary = out.strip().splitlines()[-1]
    assert f"{len(FOREIGN) + 16} bytes in" in summary and "0 collisions" in summary
    assert f"{16 + len(FOREIGN) + 16} bytes out" in summary
    # the fault's bytes for node 0, which no program had open yet: not written, and counted
    # as such, not as a slow reader's
    assert "0 dropped (slow reader), 16 not delivered (node not open)" in summary


# -- captures: rprs radio-hub --pcap ---------------------------------------------------------

def _capture_packets(data: bytes):
    import io

    import pcapng
    ifaces, out = {}, []
    for b in pcapng.FileScanner(io.BytesIO(data)):
        name = type(b).__name__
        if name == "InterfaceDescription":
            ifaces[len(ifaces)] = b.options["if_name"]
        elif name == "EnhancedPacket":
            ns = (b.timestamp_high << 32) + b.timestamp_low
            out.append((ifaces[b.interface_id], ns, bytes(b.packet_data),
                        b.options.get("opt_comment")))
    return out


def test_a_capture_has_one_packet_per_burst_at_wall_clock_time(hubs):
    import io

    from hil.sim.faults import parse_fault
    from hil.sim.pcap import PcapWriter

    class Sink(io.BytesIO):
        def close(self):
            pass

    sink = Sink()
    hub = hubs(3, faults=[parse_fault(f"foreign@0.5:x{FOREIGN.hex()}")])
    hub.capture(PcapWriter(sink, *hub.capture_interfaces(), tsresol=9))
    fds = [open_node(hubs, p) for p in hub.paths]
    before = time.time_ns()
    hub.start()
    a, b = b"A" * 60, b"B" * 60
    os.write(fds[1], a)                        # written in two pieces, the second while the
    time.sleep(0.02)                           # first is on air (62 ms): one packet
    os.write(fds[1], b)
    assert read_n(fds[2], 120, 5.0)[0] == a + b
    assert read_n(fds[0], 120 + len(FOREIGN), 5.0)[0].endswith(FOREIGN)
    hub.close()
    after = time.time_ns()
    pkts = _capture_packets(sink.getvalue())
    mine = [p for p in pkts if p[0] == "node 1 radio"]
    assert [(p[2], p[3]) for p in mine] == [(a + b, None)]
    foreign = [p for p in pkts if p[0] == "foreign transmitters"]
    assert [p[2] for p in foreign] == [FOREIGN] and "no robot" in foreign[0][3]
    # timestamps: the wall clock (ns) when the burst's last stop bit ended
    assert before + 120 * BYTE_S * 1e9 <= mine[0][1] <= after
    assert before + (0.5 + len(FOREIGN) * BYTE_S) * 1e9 <= foreign[0][1] <= after


def test_a_collision_is_in_the_capture_and_marked(hubs):
    import io

    from hil.sim.pcap import PcapWriter
    sink = io.BytesIO()
    hub = hubs(3)
    hub.capture(PcapWriter(sink, *hub.capture_interfaces(), tsresol=9))
    hub.start()
    fds = [open_node(hubs, p) for p in hub.paths]
    os.write(fds[0], FRAME)
    os.write(fds[1], FRAME)
    read_for(fds[2], 0.3)
    assert hub.stats()["collisions"] >= 1
    pkts = _capture_packets(sink.getvalue())
    sent = [p for p in pkts if p[0] in ("node 0 radio", "node 1 radio")]
    assert len(sent) == 2 and all(p[2] == FRAME and "collided" in p[3] for p in sent)


TSHARK = shutil.which("tshark")


@pytest.mark.skipif(TSHARK is None, reason="tshark not installed (Debian package tshark; "
                    ".ci/run installs it)")
def test_live_capture_through_a_pipe_into_tshark():
    """rprs radio-hub --pcap - | tshark -i -: tshark decodes each frame as it comes."""
    from hil.wireshark import plugin_path
    hub = subprocess.Popen([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                            "--pcap", "-"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    shark = subprocess.Popen([TSHARK, "-l", "-X", f"lua_script:{plugin_path()}", "-i", "-",
                              "-T", "fields", "-e", "frame.interface_name", "-e", "rprs.src",
                              "-e", "rprs.num", "-e", "rprs.content"],
                             stdin=hub.stdout, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)
    hub.stdout.close()
    try:
        paths = [hub.stderr.readline().decode().split()[2] for _ in range(2)]
        fd = os.open(paths[0], os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(fd, FRAME)
            # live: tshark prints the frame while the hub still runs
            r, _, _ = select.select([shark.stdout], [], [], 20.0)
            assert r, "tshark printed nothing while the hub ran"
            line = shark.stdout.readline()
        finally:
            os.close(fd)
        assert line.split("\t") == ["node 0 radio", "0", "12",
                                    "movex(10)moveto(1.5,-2,0)\n"]
        hub.send_signal(signal.SIGINT)
        assert hub.wait(timeout=10) == 0
        rest, err = shark.communicate(timeout=20)
        assert shark.returncode == 0, err
    finally:
        for p in (hub, shark):
            _kill(p)
        with hub.stderr:                  # closed, or the pipe warns when hub is collected
            err = hub.stderr.read().decode()
        for f in (shark.stdout, shark.stderr):
            f.close()                     # communicate() closed them, unless it never ran
    assert "radio-hub: " in err


def _packets_so_far(path) -> list:
    """The packets of a capture still being written ([] until a whole one is there)."""
    try:
        return _capture_packets(path.read_bytes())
    except Exception:                   # (empty, or a block half written)
        return []


def test_a_capture_to_a_file_has_each_frame_as_it_comes_and_keeps_it_if_the_hub_is_killed(
        tmp_path):
    """``rprs radio-hub --pcap hub.pcapng`` buffered a regular file's packets until it
    stopped: after 25 frames the file was still empty, and a hub that was killed (SIGKILL,
    out of memory, power) left 0 bytes, where ``rprs child --pcap`` had written every packet.
    Each packet is now on disk as it comes, to a file as to a pipe."""
    cap = tmp_path / "hub.pcapng"
    hub = subprocess.Popen([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                            "--pcap", str(cap)], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    try:
        paths = [hub.stdout.readline().split()[2] for _ in range(2)]
        fd = os.open(paths[0], os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(fd, FRAME)
            deadline = time.monotonic() + 20
            while not _packets_so_far(cap) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert _packets_so_far(cap), "nothing on disk while the hub ran"
        finally:
            os.close(fd)
        hub.kill()
        hub.wait(timeout=10)
        pkts = _capture_packets(cap.read_bytes())
        assert [p[2] for p in pkts] == [FRAME]
    finally:
        _kill(hub)
        for f in (hub.stdout, hub.stderr):
            f.close()


def test_a_capture_that_cannot_be_written_is_one_line(tmp_path):
    r = subprocess.run([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                        "--pcap", str(tmp_path / "no" / "x.pcapng")],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and "cannot write capture" in r.stderr
    assert "Traceback" not in r.stderr


def test_the_foreign_fault_goes_out_at_the_hubs_own_rate(hubs):
    """On a hub at another --baud than 9600 the foreign transmitter sends at that rate too
    (at 9600 the nodes' UARTs heard its bytes as garbage, a rate they do not read)."""
    from hil.sim.faults import parse_fault
    hub = hubs(2, baud=64000, faults=[parse_fault(f"foreign@0.1:x{FOREIGN.hex()}")])
    fds = [open_node(hubs, p) for p in hub.paths]
    hub.start()
    for fd in fds:
        got, _ = read_n(fd, len(FOREIGN), 10.0)
        assert got == FOREIGN


def test_every_documented_link_dir_can_be_made_on_a_fresh_machine():
    """docs/bench.md's walk-through began ``rprs radio-hub --nodes 4 --link-dir /tmp/wk/air``,
    which on a fresh machine ends at once: ``its parent directory /tmp/wk does not exist (the
    hub makes only the last directory)``. Every ``--link-dir DIR`` in a command of the docs
    names a directory whose parent exists anywhere (``/tmp``) or that an earlier command of
    the same page makes (``mkdir -p``)."""
    from doc_commands import dirs_without_parent
    seen, bad = dirs_without_parent(r"--link-dir (/[^\s`]+)")
    assert not bad, bad
    assert seen >= 4
