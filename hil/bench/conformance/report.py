"""What a run of the kit finds: a check per clause, the report and its JUnit XML, a frame heard
with its times, and the error that stops a run."""
from __future__ import annotations

from dataclasses import dataclass, field
from xml.etree import ElementTree as ET

from firmware_model.radio.frame import Frame


@dataclass
class Check:
    """One verdict: the clause, what was checked, passed or not, and the measured figure.
    ``applicable`` False: nothing was there to check (a robot that answered with JOIN has no
    BOOT frame for clause 29); the verdict is ``n/a``, ``figure`` says why, and it counts as
    no failure."""

    clause: str
    name: str
    passed: bool
    figure: str
    seconds: float = 0.0
    applicable: bool = True

    @property
    def verdict(self) -> str:
        """``pass``, ``FAIL`` or ``n/a``."""
        return "n/a" if not self.applicable else "pass" if self.passed else "FAIL"


@dataclass
class Heard:
    frame: Frame
    start: int          # estimated tick the Header's first bit began
    end: int            # tick the End's last byte arrived


@dataclass
class Report:
    robot: int
    profile: str
    checks: list[Check] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)    # what no clause judges: missed turns
    stopped: str | None = None
    """Why the run stopped before its last check (ConformanceError, a port that failed), or
    None: a run that stopped has not passed, whatever it had checked."""

    @property
    def passed(self) -> bool:
        """The run went to its end, something was checked, and every clause passed or was
        not applicable."""
        return self.stopped is None and any(c.applicable for c in self.checks) and \
            all(c.passed or not c.applicable for c in self.checks)

    def junit(self) -> bytes:
        """JUnit XML: one testcase per clause, a failure element where it failed, a skipped
        element with the reason where it was not applicable; a run that stopped, one more
        testcase with an error element that says why."""
        suite = ET.Element("testsuite", name=f"rprs conformance robot {self.robot} "
                           f"({self.profile})",
                           tests=str(len(self.checks) + (self.stopped is not None)),
                           failures=str(sum(c.verdict == "FAIL" for c in self.checks)),
                           errors=str(int(self.stopped is not None)),
                           skipped=str(sum(c.verdict == "n/a" for c in self.checks)))
        # in the order the JUnit schema (Ant's, Jenkins') gives: a testcase's failure or
        # skipped before its system-out, the suite's system-out after its testcases
        for c in self.checks:
            case = ET.SubElement(suite, "testcase", classname=f"clause {c.clause}",
                                 name=c.name, time=f"{c.seconds:.3f}")
            if c.verdict == "FAIL":
                ET.SubElement(case, "failure", message=c.figure)
            elif c.verdict == "n/a":
                ET.SubElement(case, "skipped", message=f"not applicable: {c.figure}")
            ET.SubElement(case, "system-out").text = c.figure
        if self.stopped is not None:
            # the checks the run never reached: a CI reading the XML must not pass it
            case = ET.SubElement(suite, "testcase", classname="run", name="the run goes to "
                                 "its end", time="0.000")
            ET.SubElement(case, "error", message=f"stopped: {self.stopped}")
        if self.notes:
            ET.SubElement(suite, "system-out").text = "\n".join(self.notes)
        return ET.tostring(suite, encoding="utf-8", xml_declaration=True)


class ConformanceError(Exception):
    """The run could not go on (no answer at all, a port that broke): one line. ``shared``:
    it stopped because the channel carries other stations (nothing is judged then)."""

    def __init__(self, message: str, shared: bool = False) -> None:
        super().__init__(message)
        self.shared = shared
