"""docs/protocol.md, the normative spec, against the code: every hex example is rebuilt with the
project's frame code, the worked conversation is replayed with the MAC itself, the state diagram
and its table are the MAC's transition table, the timing tables hold the code's constants, and
the clause and section references resolve. So the spec cannot drift from the code.

Run ``python tests/docs/test_protocol_doc.py`` to print the example blocks the document must
hold."""
from __future__ import annotations

import heapq
import re


from firmware_model.radio import integrity
from firmware_model.radio.content import cmd, frame_kind
from firmware_model.radio.frame import Frame, parse_frame
from firmware_model.radio.mac import Deliver, MacConfig, RotationalMac, Transmit
from firmware_model.radio.mac_table import PAPER_PROFILE, STATES, TRANSITIONS
from firmware_model.timing import (
    CHILD_BYTE_TICKS,
    MISS_LIMIT,
    PC_BYTE_TICKS,
    TICK_HZ,
    TMAX_TICKS,
    TTRANS_TICKS,
    max_content_bytes,
    protocol_max_content,
)
from hil.bench.runner import REALTIME_MARGINS
from paths import ROOT

DOC = ROOT / "docs" / "protocol.md"
MS = TICK_HZ // 1000


def doc() -> str:
    return DOC.read_text(encoding="utf-8")


def blocks(info: str) -> list[str]:
    """The bodies of the fenced blocks of ``info`` (e.g. ```frame) in the document, in order."""
    return re.findall(rf"^```{info}\n(.*?)^```$", doc(), flags=re.S | re.M)


# ----------------------------------------------------------------------------------------------
# The examples, as the code makes them
# ----------------------------------------------------------------------------------------------

def hex_fields(data: bytes) -> str:
    """``0f0a05 37 31 3030 33 30303030 - 1719``: the bytes grouped by field."""
    n = len(data) - 14
    parts = [data[0:3], data[3:4], data[4:5], data[5:7], data[7:8], data[8:12], data[12:12 + n],
             data[12 + n:]]
    return " ".join(p.hex() if p else "-" for p in parts)


def frame_block(kind: str, frame: Frame, checksum: bool = False) -> str:
    fields = (f'dst={frame.dst} src={frame.src} num={frame.num:02d} type={frame.type} '
              f'content="{frame.content.decode()}"' + (" checksum" if checksum else ""))
    return f"kind   {kind}\nfields {fields}\nhex    {hex_fields(frame.encode())}\n"


REPLY = (cmd("joint", 1, 0), cmd("joint", 2, 45), cmd("joint", 3, -90), cmd("joint", 4, 45),
         cmd("wheel", 0), cmd("paw", 0))
"""What child 1 answers to ``status()`` in the examples (its arm at rest, docs/dispatcher.md)."""


def examples() -> list[str]:
    """The §8.1 blocks, in the document's order."""
    reply = "".join(c.text() for c in REPLY).encode() + b"ack(4,1)"
    return [
        frame_block("heartbeat", Frame(7, 1, 0, 3, b"")),
        frame_block("control", Frame(7, 1, 0, 3, b"poll(4,2)")),
        frame_block("boot", Frame(7, 4, 0, 5, b"")),
        frame_block("join", Frame(7, 4, 2, 6, b"")),
        frame_block("control", Frame(7, 1, 0, 3, b"ack(4,0)")),
        frame_block("message", Frame(1, 4, 1, 2, b"status()")),
        frame_block("control", Frame(7, 1, 0, 3, b"ack(4,1)")),
        frame_block("message", Frame(4, 1, 1, 3, reply)),
        frame_block("control", integrity.seal(7, 1, 0, 3, b""), checksum=True),
        frame_block("message", integrity.seal(1, 4, 1, 2, b"status()"), checksum=True),
    ]


def conversation() -> list[tuple[int, bytes]]:
    """§8.2: child 1 and robot 4 (team {1, 4}, exact margins) on a perfect channel, driven
    through the MAC's own events; returns (tick the frame's first bit starts, bytes) per frame.

    Child 1 powers on at 0 ms and robot 4 at 1000 ms; robot 4 submits ``status()`` for child 1
    at 1340 ms and child 1's application answers it at once; robot 4's radio is off (it neither
    sends nor hears) from 1500 to 3600 ms."""
    cfg = MacConfig(team=frozenset({1, 4}))
    macs = {1: RotationalMac(1, cfg), 4: RotationalMac(4, cfg)}
    off = {4: (1500 * MS, 3600 * MS)}
    until = 3760 * MS
    on: set[int] = set()
    air: list[tuple[int, int, int]] = []          # (first bit, end, sender)
    queue: list = []
    log: list[tuple[int, bytes]] = []
    seq = 0

    def push(t: int, *event) -> None:
        nonlocal seq
        seq += 1
        heapq.heappush(queue, (t, seq, event))

    def alive(robot: int, t: int) -> bool:
        a, b = off.get(robot, (0, 0))
        return not a <= t < b

    def act(robot: int, actions, now: int) -> None:
        for a in actions:
            if type(a) is Transmit:
                end = now + len(a.data) * CHILD_BYTE_TICKS
                push(end, "tx done", robot)
                if alive(robot, now):
                    log.append((now, a.data))
                    air.append((now, end, robot))
                    for other in macs:
                        if other != robot:
                            push(end, "frame", other, a.frame, now + CHILD_BYTE_TICKS)
            elif type(a) is Deliver and a.commands == (cmd("status"),):
                push(now, "submit", robot, a.src, REPLY, 3)

    push(0, "power", 1)
    push(1000 * MS, "power", 4)
    push(1340 * MS, "submit", 4, 1, (cmd("status"),), 2)
    while True:
        due = min(((m.deadline, r) for r, m in macs.items() if r in on and m.deadline is not None),
                  default=None)
        if queue and (due is None or queue[0][0] <= due[0]):   # bytes before timers at a tick
            t, _, (kind, robot, *rest) = heapq.heappop(queue)
            if t > until:
                break
            mac = macs[robot]
            if kind == "power":
                on.add(robot)
                act(robot, mac.power_on(t), t)
            elif kind == "tx done":
                act(robot, mac.on_tx_done(t), t)
            elif kind == "frame" and robot in on and alive(robot, t) and \
                    alive(robot, rest[1] - CHILD_BYTE_TICKS):
                # heard only if its radio was on for the whole frame, first bit to End (a
                # radio back on mid-frame hears no Header: clause 15)
                act(robot, mac.on_frame(rest[0], rest[1], t, t), t)
            elif kind == "submit":
                mac.submit(rest[0], rest[1], t, rest[2])
        elif due is not None:
            t, robot = due
            if t > until:
                break
            began = next((s for s, e, src in air if src != robot and s <= t < e), None)
            if not alive(robot, t):
                began = None
            busy = began is not None and t >= began + 3 * CHILD_BYTE_TICKS
            act(robot, macs[robot].on_timer(t, busy, None, began), t)
        else:
            break
    return log


def transcript() -> str:
    """The §8.2 block: one line a frame."""
    lines = ["  t (ms)   gap  from  bytes (Header Dst Src Number Type Length Content End)  kind"]
    prev_end = None
    for t, data in conversation():
        f = parse_frame(data)
        gap = "" if prev_end is None else f"{(t - prev_end) / MS:.2f}"
        lines.append(f"{t / MS:8.2f} {gap:>6}  R{f.src}    {hex_fields(data)}  "
                     f"{frame_kind(f.type, f.content)}")
        prev_end = t + len(data) * CHILD_BYTE_TICKS
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------------------
# The document against them
# ----------------------------------------------------------------------------------------------

FIELDS = re.compile(r'dst=(\d) src=(\d) num=(\d\d) type=(\d) content="([^"]*)"( checksum)?$')


def test_every_hex_example_is_what_the_frame_code_encodes():
    held = blocks("frame")
    assert held, "docs/protocol.md has no ```frame examples"
    for block in held:
        lines = dict(line.split(None, 1) for line in block.strip().splitlines())
        m = FIELDS.match(lines["fields"])
        assert m, lines["fields"]
        dst, src, num, typ = (int(x) for x in m.groups()[:4])
        content, checksum = m.group(5).encode(), bool(m.group(6))
        parts = lines["hex"].split()
        assert len(parts) == 8, f"hex must be grouped in the 8 fields: {lines['hex']}"
        data = bytes.fromhex("".join(p for p in parts if p != "-"))
        if checksum:
            built = integrity.seal(dst, src, num, typ, integrity.strip(content))
            assert built.content == content, f"wrong checksum in the example: {block}"
        else:
            built = Frame(dst, src, num, typ, content)
        assert built.encode() == data, f"the frame code encodes\n{hex_fields(built.encode())}\n" \
                                       f"not\n{lines['hex']}"
        assert hex_fields(data) == lines["hex"], "grouped by the wrong field boundaries"
        assert parse_frame(data) == built
        assert frame_kind(typ, content) == lines["kind"], block
        assert integrity.check(built) == checksum


def test_the_examples_are_the_generated_ones_and_cover_every_kind():
    assert blocks("frame") == examples(), \
        "docs/protocol.md §8.1 is stale: python tests/docs/test_protocol_doc.py prints the blocks"
    kinds = {b.splitlines()[0].split()[1] for b in examples()}
    assert {"heartbeat", "control", "boot", "join", "message"} <= kinds
    text = "".join(examples())
    for needle in ("poll(", "ack(", "status()", "checksum"):
        assert needle in text


def test_the_conversation_is_what_the_mac_does():
    held = blocks("transcript")
    assert len(held) == 1, "docs/protocol.md must hold one ```transcript block"
    assert held[0] == transcript(), \
        "docs/protocol.md §8.2 is stale: python tests/docs/test_protocol_doc.py prints the block"


def test_the_conversation_shows_the_join_handshake_a_message_and_a_drop():
    frames = [(t, parse_frame(d)) for t, d in conversation()]
    kinds = [frame_kind(f.type, f.content) for _, f in frames]
    assert kinds[0] == "boot" and "join" in kinds
    polls = [f for _, f in frames if b"poll(4," in f.content]
    assert polls and frames[kinds.index("boot", 1)][1].src == 4
    assert any(f.dst == 1 and f.content == b"status()" for _, f in frames)
    assert any(f.dst == 4 and f.content.endswith(b"ack(4,1)") for _, f in frames)
    gaps = [(b - a) / MS for (a, _), (b, _) in zip(frames, frames[1:])]
    assert sum(1 for g in gaps if g > 600) == 3              # three misses of robot 4


# ----------------------------------------------------------------------------------------------
# The state machine
# ----------------------------------------------------------------------------------------------

def _code_rows() -> set[tuple[str, str, str]]:
    return {(t.state, t.event, t.next) for t in TRANSITIONS
            if t.source not in ("fault", PAPER_PROFILE)}


def test_the_state_diagram_is_the_macs_transition_table():
    (diagram,) = blocks("mermaid")
    drawn: dict[tuple[str, str], set[str]] = {}
    for a, b, label in re.findall(r"^\s*(\S+) --> (\S+): (.*)$", diagram, flags=re.M):
        drawn.setdefault((a, b), set()).update(e.strip() for e in label.split(","))
    want: dict[tuple[str, str], set[str]] = {("[*]", "LISTEN"): {"power on"}}
    for state, event, nxt in _code_rows():
        if state != nxt:
            want.setdefault((state, nxt), set()).add(event)
    assert drawn == want
    inner = re.search(r"state MEMBER \{(.*?)\}", diagram, flags=re.S).group(1)
    assert "LISTEN" not in inner, "LISTEN is a mode of its own, outside MEMBER"


def test_the_transition_table_is_the_macs_and_cites_existing_clauses():
    text = doc()
    rows = re.findall(r"^\| (LISTEN|WAIT|WINDOW|QUIET|HOLD|SWITCH|SEND|WATCH) \| ([a-z ]+) \| "
                      r"([A-Z]+) \| [^|]+ \| ([\d, ]+) \|$", text, flags=re.M)
    assert {(a, b, c) for a, b, c, _ in rows} == _code_rows()
    assert len(rows) == len(_code_rows()), "a transition is listed twice"
    clauses = clause_numbers()
    for *_, cited in rows:
        for n in cited.split(","):
            assert int(n) in clauses, cited


def table_clauses(text: str | None = None) -> dict[tuple[str, str, str], set[int]]:
    """§6's table: (state, event, next) -> the clauses its last column cites."""
    rows = re.findall(r"^\| (LISTEN|WAIT|WINDOW|QUIET|HOLD|SWITCH|SEND|WATCH) \| ([a-z ]+) \| "
                      r"([A-Z]+) \| [^|]+ \| ([\d, ]+) \|$", text or doc(), flags=re.M)
    return {(a, b, c): {int(n) for n in cited.split(",")} for a, b, c, cited in rows}


GUARD_EVENT = re.compile(r"^  on (power on|frame|failed frame|garbage|tx done|deadline)\b")
GUARD = re.compile(r" -> ([A-Z]+) +\[(\d+(?:, \d+)*)\]( †)?$")


def guards(text: str | None = None) -> list[tuple[str, str, str, set[int], bool]]:
    """§6.1's pseudo-code: (state, event, next, clauses, marked †) for every ``-> NEXT [..]``
    line, in the document's order. A block opens with its state's name; ``  on EVENT`` sets the
    event of the lines after it (and of its own line)."""
    found = []
    for block in re.findall(r"^```guards\n(.*?)^```$", text or doc(), flags=re.S | re.M):
        state = block.split(None, 1)[0]
        event = None
        for line in block.splitlines():
            m = GUARD_EVENT.match(line)
            if m:
                event = m.group(1)
            if "->" not in line:
                continue
            g = GUARD.search(line)
            assert g, f"a guard must end in '-> STATE [clauses]': {line!r}"
            assert state in STATES and event, f"a guard outside a state's event: {line!r}"
            assert g.group(1) in STATES, line
            found.append((state, event, g.group(1), {int(n) for n in g.group(2).split(",")},
                          bool(g.group(3))))
    return found


def guard_problems(text: str | None = None) -> list[str]:
    """What is wrong between §6.1's guards and the MAC's transition table (empty: nothing).

    Unmarked lines must be rows of TRANSITIONS (without the fault injection's ``steal``, not
    in the spec), lines marked † must not be (they are paths no simulated run takes: once a
    run does and the row exists, the mark goes), every row must have a line, and the clauses
    of a row in §6's table must be exactly those its lines cite: a line's clauses are a
    subset of its row's, and none of the row's is cited by no line."""
    text = text or doc()
    rows, cited = _code_rows(), table_clauses(text)
    lines = guards(text)
    problems = []
    union: dict[tuple[str, str, str], set[int]] = {}
    for state, event, nxt, clauses, marked in lines:
        key = (state, event, nxt)
        if marked:
            if key in rows:
                problems.append(f"{key} is a row of the table: drop its † mark")
            continue
        if key not in rows:
            problems.append(f"{key} is no row of the table (mark it † if no run takes it)")
            continue
        if not clauses <= cited[key]:
            problems.append(f"{key} cites {sorted(clauses - cited[key])}, not in its row")
        union.setdefault(key, set()).update(clauses)
    for key in sorted(rows - set(union)):
        problems.append(f"the row {key} has no guard")
    for key, clauses in sorted(union.items()):
        if clauses != cited[key]:
            problems.append(f"{key}: the table cites {sorted(cited[key] - clauses)}, "
                            f"which no guard does")
    return problems


def test_the_guards_are_one_block_per_state_in_the_tables_order():
    heads = [b.split(None, 1)[0]
             for b in re.findall(r"^```guards\n(.*?)^```$", doc(), flags=re.S | re.M)]
    assert [h for h in heads if h in STATES] == list(STATES)
    assert all(h in STATES for h in heads[1:]), "definitions come before the states"


def test_the_guards_are_the_macs_transition_table():
    lines = guards()
    assert len(lines) >= len(_code_rows())
    assert not guard_problems(), "\n".join(guard_problems())
    clauses = clause_numbers()
    for *_, cited, _marked in lines:
        assert cited <= set(clauses), cited


def test_the_guard_check_catches_a_dropped_line_or_a_wrong_target():
    """The check above is not vacuous: deleting a guard line, changing its target, its
    clauses or its mark makes it fail."""
    text = doc()
    line = "succ(s) == me: TXEN at E, Header at E + Ttrans"
    start = text.index(line)
    end = text.index("\n", start)
    full = text[text.rindex("\n", 0, start) + 1:end]
    assert full.endswith("-> SWITCH [23, 39]"), full
    assert "('WAIT', 'frame', 'SWITCH')" in " ".join(guard_problems(text.replace(full + "\n", "")))
    assert guard_problems(text.replace(full, full.replace("SWITCH", "WAIT  ")))
    assert guard_problems(text.replace(full, full.replace("[23, 39]", "[23, 40]")))
    assert guard_problems(text.replace(full, full + " †"))
    sent = "    else WAIT for succ(me) until E + Tmax ............................. -> WAIT   [22]"
    assert sent in text
    not_a_row = sent.replace("WAIT   [22]", "SEND   [22]")      # (SEND, tx done, SEND)
    assert guard_problems(text.replace(sent, sent + "\n" + not_a_row))
    assert not guard_problems(text.replace(sent, sent + "\n" + not_a_row + " †"))


# ----------------------------------------------------------------------------------------------
# Numbers, clauses, references
# ----------------------------------------------------------------------------------------------

def ticks(n: int) -> str:
    return f"{n:,}".replace(",", " ")


def cells(first_cell: str, after: str = "## 2. Timing") -> list[str]:
    """The cells after the first of the first table row that begins with ``first_cell``,
    looking from ``after`` on."""
    text = doc()
    m = re.search(rf"^\| {re.escape(first_cell)} \|(.*)\|$", text[text.index(after):], flags=re.M)
    assert m, f"no table row {first_cell!r} in docs/protocol.md"
    return [c.strip() for c in re.split(r"(?<!\\)\|", m.group(1))]


def test_the_timing_tables_hold_the_codes_constants():
    cfg = MacConfig()
    assert cells("B (child)")[:2] == [ticks(CHILD_BYTE_TICKS), f"{CHILD_BYTE_TICKS / MS:g}"]
    assert cells("B (PC)")[:2] == [ticks(PC_BYTE_TICKS), f"{PC_BYTE_TICKS / MS:.4f}"]
    assert cells("Ttrans")[:2] == [ticks(TTRANS_TICKS), f"{TTRANS_TICKS // MS}"]
    assert cells("Tmax")[:2] == [ticks(TMAX_TICKS), f"{TMAX_TICKS // MS}"]
    assert cells("miss limit")[0] == f"{MISS_LIMIT}"
    assert cells("P")[0] == f"{cfg.poll_every}"
    assert cells("A")[0] == f"{cfg.max_attempts}"
    assert cells("announcement limit")[0] == f"{2 * MISS_LIMIT}"
    assert cells("max age")[:2] == [ticks(cfg.max_age), ticks(cfg.max_age // MS)]
    assert cells("Tclaim(id)")[0] == "\\|team\\| × Tmax + id × Tslot"
    assert cfg.claim_ticks(2) == len(cfg.team) * cfg.tmax + 2 * cfg.tslot
    for name, field in (("Twin", "twin"), ("Tslot", "tslot"), ("quiet gap", "quiet_gap"),
                        ("stall gap", "stall_gap")):
        exact, real = cells(name, after="**Clause 5 ")
        assert exact.startswith(f"{ticks(getattr(cfg, field))} ticks"), (name, exact)
        assert real.startswith(f"{ticks(REALTIME_MARGINS[field])} ticks"), (name, real)
    exact, real = cells("W", after="**Clause 5 ")
    assert exact.startswith(f"{ticks(max(4 * PC_BYTE_TICKS, cfg.standby_watch))} ticks")
    assert real.startswith(f"{ticks(REALTIME_MARGINS['standby_watch'])} ticks")


def test_the_bounds_are_the_codes():
    text = doc()
    assert protocol_max_content() == 562 and "up to **562**" in text
    assert max_content_bytes(CHILD_BYTE_TICKS) == 562 and max_content_bytes(PC_BYTE_TICKS) == 561
    assert "**576 bytes** (562 of Content)" in text and "**575 bytes** (561)" in text
    idle = 14 * CHILD_BYTE_TICKS + TTRANS_TICKS
    assert f"**{ticks(idle)} ticks = {idle / MS:.2f} ms**" in text
    assert f"Ttrans + 3 B = {ticks(TTRANS_TICKS + 3 * PC_BYTE_TICKS)} ticks" in text
    assert f"{ticks(2 * (TTRANS_TICKS + 4 * PC_BYTE_TICKS))} ticks" in text
    assert integrity.crc16(b"123456789") == 10673 and "`crc(10673)`" in text


def clause_numbers() -> list[int]:
    return [int(n) for n in re.findall(r"^\*\*Clause (\d+) — ", doc(), flags=re.M)]


def test_clauses_are_numbered_once_in_order_and_every_citation_resolves():
    numbers = clause_numbers()
    assert numbers == list(range(1, len(numbers) + 1))
    heads = re.findall(r"^\*\*Clause \d+ — [^*]+\*\* \*\(([^)]*)\)\*", doc(), flags=re.M)
    assert len(heads) == len(numbers), "every clause says whose rule it is"
    assert all("paper" in h or "designed" in h for h in heads)
    for n in re.findall(r"[Cc]lauses? (\d+)", doc()):
        assert int(n) in numbers, f"clause {n} is cited but does not exist"


def sections() -> set[str]:
    return set(re.findall(r"^#{2,3} (\d+(?:\.\d+)?)\. ?", doc(), flags=re.M)) | \
        set(re.findall(r"^### (\d+\.\d+) ", doc(), flags=re.M))


def repo_files():
    skip = {".git", ".venv", "__pycache__", ".pytest_cache", ".hypothesis", "build", "dist",
            ".cache"}
    for path in sorted(ROOT.rglob("*")):
        rel = path.relative_to(ROOT)
        if any(part in skip or part.endswith(".egg-info") for part in rel.parts):
            continue
        if path.is_file():
            try:
                yield rel, path.read_text(encoding="utf-8")
            except (UnicodeDecodeError, OSError):
                continue


def test_references_to_the_spec_name_sections_it_has():
    have = sections()
    assert {"0", "1", "2", "3", "4", "5", "6", "7", "8", "3.1", "4.2", "7.1", "8.1"} <= have
    cited = 0
    for rel, text in repo_files():
        for sec in re.findall(r"protocol\.md\)? §(\d+(?:\.\d+)?)", text):
            cited += 1
            assert sec in have, f"{rel} cites docs/protocol.md §{sec}, which does not exist"
        for n in re.findall(r"protocol\.md[^\n]{0,40}?clause (\d+)", text):
            assert int(n) in clause_numbers(), f"{rel} cites clause {n}, which does not exist"
    assert cited >= 20


def test_nothing_in_the_repository_points_outside_it():
    # Built from pieces, so that this file does not match itself.
    banned = ["PROTOCOL" + ".md", "../" + "shared", "/work/" + "shared", "shared/" + "reference"]
    found = [f"{rel}: {b}" for rel, text in repo_files() for b in banned if b in text]
    assert not found, "the repository must not point at files outside it:\n" + "\n".join(found)
    for rel, text in repo_files():
        if rel.suffix != ".md":
            continue
        for target in re.findall(r"\]\(([^)#\s]+)", text):
            if "://" in target or target.startswith("mailto:"):
                continue
            resolved = (ROOT / rel).parent.joinpath(target).resolve()
            assert resolved.is_relative_to(ROOT), f"{rel} links outside the repository: {target}"


if __name__ == "__main__":       # print the blocks docs/protocol.md §8 holds
    for block in examples():
        print(f"```frame\n{block}```\n")
    print(f"```transcript\n{transcript()}```")


def test_clause_19a_names_the_order_types_and_the_failure_codes_the_child_uses():
    """Clause 19a (orders and information) is normative: its order Types are the dispatcher's
    REQUEST_TYPES, and its failure-code table holds exactly the codes the child answers with
    (each constant of the dispatcher and the kinematics), no more."""
    from firmware_model import dispatcher as d
    from firmware_model import kinematics as k
    text = doc()
    start = text.index("**Clause 19a — Orders and information**")
    clause = text[start:text.index("\n**Clause", start + 10)]
    assert "only those of Type `'0'`, `'1'` or `'2'` are **orders**" in clause
    assert d.REQUEST_TYPES == {0, 1, 2}
    rows = re.findall(r"^\| (\d+)(\+n)? \| ", clause, flags=re.M)
    table = {(int(c), bool(n)) for c, n in rows}
    code = {(k.CODE_UNREACHABLE, False), (k.CODE_JOINT_LIMIT, False), (d.CODE_RANGE, False),
            (d.CODE_FAULT, True), (d.CODE_REFUSED, True), (d.CODE_SILENT, True),
            (d.CODE_SILENT, False), (d.CODE_BUS_OFF, False), (d.CODE_BLOCKED, False),
            (d.CODE_NO_CAN, False)}
    assert table == code and len(rows) == len(code)
