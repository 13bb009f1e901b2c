"""The father's live console (hil/view/father_app.py), headless with textual's pilot."""
from __future__ import annotations

import asyncio
import threading

import pytest

pytest.importorskip("textual")

from hil.view.father_app import FatherApp, LinesTo  # noqa: E402
from pilots import stopped_within  # noqa: E402

SIZE = (120, 30)


def test_typed_orders_history_refusals_and_the_story(tmp_path):
    hist = tmp_path / "history"
    hist.write_text("1 status()\n")
    sent: list[str] = []
    state = {"ring": "[father 0 R1]"}

    def submit(line: str):
        if not line[0].isdigit():
            return "start with the destination ID (1-7)"
        sent.append(line)
        return None

    app = FatherApp(submit, lambda: f"ring {state['ring']}", str(hist), rate=10.0)

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press(*"1 joint(2,60)", "enter")
            await pilot.press(*"status()", "enter")           # no destination: refused
            assert sent == ["1 joint(2,60)"]
            assert app.lines[-1].startswith("not sent: status(): start with the destination")
            await pilot.press("up", "up")                       # the history, newest first
            assert app.query_one("#order").value == "1 joint(2,60)"
            await pilot.press("up")
            assert app.query_one("#order").value == "1 status()"   # from an earlier run
            await pilot.press("enter")
            assert sent == ["1 joint(2,60)", "1 status()"]
            # lines from the firmware's thread arrive in the story
            out = LinesTo(app.post_line)
            t = threading.Thread(target=out.write, args=("    2.00 s  #1 -> R1 joint(2,60): "
                                                          "done in 0.40 s\n",))
            t.start()
            t.join()                                            # posting never waits
            await pilot.pause(0.2)
            assert app.lines[-1].endswith("done in 0.40 s")
            state["ring"] = "[father 0 R1 R2]"
            await pilot.pause(0.1)
            assert "[father 0 R1 R2]" in str(app.query_one("#head").render())
            await pilot.press("ctrl+q")
    asyncio.run(go())
    assert hist.read_text().splitlines() == ["1 status()", "1 joint(2,60)", "status()",
                                             "1 status()"]


def test_tab_completes_a_command_name_after_the_destination_or_another_command(tmp_path):
    """``1 jo`` + Tab gives ``1 joint(``; after a command's ``)`` the next one completes too;
    a prefix of two names (``st``: status, stop) or the destination alone gets nothing."""
    sent: list[str] = []
    app = FatherApp(lambda line: sent.append(line), lambda: "head", str(tmp_path / "h"),
                    rate=10.0)

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            box = app.query_one("#order")
            await pilot.press(*"1 jo", "tab")
            assert box.value == "1 joint("
            await pilot.press(*"2,60)whe", "tab")
            assert box.value == "1 joint(2,60)wheel("
            await pilot.press(*"100)", "enter")
            assert sent == ["1 joint(2,60)wheel(100)"]
            await pilot.press(*"1 st", "tab")
            assert box.value == "1 st"                 # status or stop: no single name
            await pilot.press("ctrl+u")
            await pilot.press(*"1", "tab")
            assert box.value == "1"
            await pilot.press("ctrl+q")
    asyncio.run(go())


def test_the_view_quits_once_the_firmware_has_stopped_by_itself(tmp_path):
    """A lost radio port (or --duration) stops the firmware's thread; the view then quits
    instead of showing a ring that no longer runs."""
    ended = threading.Event()
    app = FatherApp(lambda line: None, lambda: "head", str(tmp_path / "h"), rate=10.0,
                    ended=ended.is_set)

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            await pilot.pause(0.3)
            assert app.is_running
            ended.set()
            for _ in range(100):                 # up to 10 s; a refresh comes every 0.1 s
                await pilot.pause(0.1)
                if not app.is_running:
                    break
            assert not app.is_running
    asyncio.run(go())


def test_ctrl_c_quits_the_view_even_from_the_order_line(tmp_path):
    """Ctrl-C in the live view only showed "Press ctrl+q to quit" (textual's own binding; the
    order line took it for copy), although the README says Ctrl-C stops rprs father. It now
    quits, with the order line focused and text in it."""
    app = FatherApp(lambda line: None, lambda: "head", str(tmp_path / "h"), rate=10.0)

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press(*"1 stat")
            await pilot.press("ctrl+c")
            assert await stopped_within(app, pilot)
    asyncio.run(go())


def test_the_header_gives_the_turn_only_of_a_member_and_says_a_standby_refuses_orders():
    """The header said "turn: R5" for a robot not in the ring (a stranger's frame, or the ring
    seen while listening). It gives the turn only while the father is a member, and only a
    member's; a standby PC says that orders given there are refused."""
    from types import SimpleNamespace

    from hil.bench.orders import OrderBook
    from hil.cli.robots import father_head
    book = OrderBook()
    mac = SimpleNamespace(mode="member", ring=(0, 1, 2), owner=5, standby=False)
    assert "turn: -;" in father_head(mac, "AIR/node0", book)
    mac.owner = 2
    assert "ring [father 0 R1 R2]; turn: R2;" in father_head(mac, "AIR/node0", book)
    listening = SimpleNamespace(mode="listen", ring=(), owner=1, standby=False)
    assert "turn: -;" in father_head(listening, "AIR/node0", book)
    mac.standby = True
    assert "member (standing by: new orders are refused until this PC takes over)" in \
        father_head(mac, "AIR/node0", book)


@pytest.mark.parametrize("how", ["SIGTERM", "ctrl-c"])
def test_sigterm_or_ctrl_c_stops_the_live_father_cleanly(tmp_path, how):
    """SIGTERM to 'rprs father' at a terminal once killed it outright (the firmware's thread
    cannot take the signal): "Terminated", status 143, no summary line, the terminal left in
    the view's modes. Now the view quits and the summary comes, status 0 (docs/bench.md).
    Ctrl-C typed at that terminal (a byte 0x03 to the view, raw mode: no signal) only said
    "Press ctrl+q"; it now stops it as cleanly."""
    import signal

    def stop(proc, type_in, wait_for):
        if how == "SIGTERM":
            proc.send_signal(signal.SIGTERM)
        else:
            type_in(b"\x03")
    code, seen = _live_father(tmp_path, [], stop)
    assert code == 0, seen[-500:]
    assert b"robot 0: " in seen.rpartition(b"DST COMMANDS")[2], seen[-500:]
    assert b"orders: 0 (" in seen.rpartition(b"DST COMMANDS")[2], seen[-500:]


def _live_father(tmp_path, args: list[str], act) -> tuple[int, bytes]:
    """Run ``rprs father`` (the live view) at a pty terminal on a pty radio, ``args`` more;
    once its view is up, ``act(proc, type_in, wait_for)`` (``type_in(bytes)`` types at the
    terminal, ``wait_for(text, timeout)`` reads it until it has shown ``text``); then wait for
    it to end. Returns its exit status and everything its terminal showed."""
    import os
    import select
    import subprocess
    import sys
    import time
    import tty
    term_m, term_s = os.openpty()
    radio_m, radio_s = os.openpty()
    tty.setraw(radio_s)
    env = dict(os.environ, TERM="xterm-256color", HOME=str(tmp_path))
    proc = subprocess.Popen([sys.executable, "-m", "hil.cli", "father", "--radio",
                             os.ttyname(radio_s), "--team", "0,1", *args], stdin=term_s,
                            stdout=term_s, stderr=term_s, env=env)
    os.close(term_s)
    seen = b""

    def drain(until, timeout: float) -> None:
        nonlocal seen
        end = time.monotonic() + timeout
        while not until() and time.monotonic() < end:
            if select.select([term_m], [], [], 0.1)[0]:
                try:
                    seen += os.read(term_m, 65536)
                except OSError:                   # the process has closed the terminal
                    return
    try:
        drain(lambda: b"DST COMMANDS" in seen or proc.poll() is not None, 60)
        assert b"DST COMMANDS" in seen, seen[-500:]
        act(proc, lambda data: os.write(term_m, data),
            lambda text, timeout: drain(lambda: text in seen, timeout))
        drain(lambda: proc.poll() is not None, 60)
        proc.wait(timeout=10)
        drain(lambda: False, 0.5)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for fd in (term_m, radio_m, radio_s):
            os.close(fd)
    return proc.returncode, seen


def test_a_line_typed_live_that_is_no_order_gets_its_record_like_a_piped_one(tmp_path):
    """Typed into the live view, ``bogus`` only showed "not sent: ..." there: no record, not
    in ``--log``, and the closing line said ``refused 0`` (docs/bench.md: every order line
    gets a record and exactly one final state)."""
    log = tmp_path / "father.log"

    def bogus(proc, type_in, wait_for):
        type_in(b"bogus\r")
        wait_for(b"refused", 30)
        type_in(b"\x03")
    code, seen = _live_father(tmp_path, ["--log", str(log)], bogus)
    assert code == 0, seen[-500:]
    closing = seen.rpartition(b"DST COMMANDS")[2]
    assert b"orders: 1 (" in closing and b"refused 1" in closing, closing[-500:]
    logged = log.read_text()
    assert "#1 'bogus': refused: bad order: start with the destination ID" in logged, logged
