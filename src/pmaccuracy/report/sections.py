"""Running a report section by section: an estimate up front, progress while it runs, and a box for a failure.

A report is a sequence of sections, each a function that appends its blocks to a
:class:`~pmaccuracy.report.document.Document` and its numbers to ``results``. :class:`SectionRunner` runs them
one after the other so that one failing section never takes the whole report down:

* before anything runs, one line on ``stream`` lists the sections and their estimated seconds (from the size
  of what each computes, :func:`estimate`), and a tqdm bar counts the sections while they run (on a terminal);
* a section that raises a :class:`~pmaccuracy.errors.PmAccuracyError` (a pose where the loops cannot close, a
  singular region, an empty workspace ...), a numerical error, or any other exception (named an internal error:
  a defect to report) is rolled back (its partial blocks removed),
  replaced by its heading and a box that names the section and the reason, recorded in
  ``results["failed_sections"]`` and announced by one :class:`SectionFailedWarning`; the next section runs.
  With ``strict=True`` the first failure is raised instead (``reproduce --strict``).
"""

from __future__ import annotations

import sys
import time
import warnings
from dataclasses import dataclass
from typing import Any, Callable, TextIO

import numpy as np
from tqdm import tqdm

from ..errors import PmAccuracyError
from ..model.plausibility import PlausibilityWarning
from .document import Document

#: Errors a section may meet in a user's robot and that must not take the report down: the library's own and
#: the numerical ones of a (near-)singular configuration.
SECTION_ERRORS = (PmAccuracyError, np.linalg.LinAlgError, FloatingPointError, ZeroDivisionError)


class ReportDependencyError(PmAccuracyError):
    """A report section needs the result of an earlier section that could not be computed."""


class SectionFailedWarning(PlausibilityWarning):
    """A report section could not be computed; the report was written with a box in its place."""


@dataclass(frozen=True)
class Section:
    """One section: its heading (as the report prints it), the function that writes it (called with no
    arguments; its return value is kept) and its estimated run time (s)."""

    title: str
    run: Callable[[], Any]
    estimate_s: float = 1.0
    heading: bool = True
    short: str = ""

    @property
    def label(self) -> str:
        """The name in the plan line and the progress bar: ``short``, else the title."""
        return self.short or self.title


@dataclass(frozen=True)
class SectionFailure:
    """What :class:`SectionRunner` records of a failed section (``results["failed_sections"]``)."""

    title: str
    reason: str
    error: str

    def to_dict(self) -> dict[str, str]:
        return {"section": self.title, "reason": self.reason, "error": self.error}


def reason_of(exc: BaseException) -> str:
    """A failure's reason on one line, as the box and the warning give it: the error's message (its type when it
    has none); an exception outside :data:`SECTION_ERRORS` is a defect of pmaccuracy, not of the input, and is
    named an internal error.

    >>> reason_of(ZeroDivisionError("float division by zero"))
    'float division by zero'
    """
    text = " ".join(str(exc).split()) or type(exc).__name__
    if not isinstance(exc, SECTION_ERRORS):
        text = (f"internal error ({type(exc).__name__}: {text}); please report it with the command line "
                "(PMACCURACY_DEBUG=1 with --strict shows the traceback)")
    return text


def estimate(points: float = 0.0, *, seconds_per_point: float = 0.0, fixed: float = 0.0) -> float:
    """A section's estimated run time (s): ``fixed + points * seconds_per_point``.

    The per-point costs are the ones measured on the project's 2-core reference machine and kept beside the
    section that uses them; the estimate is a guide for the user, never used for a decision.

    >>> estimate(10_000, seconds_per_point=1e-3, fixed=0.5)
    10.5
    """
    return float(fixed + points * seconds_per_point)


def format_seconds(seconds: float) -> str:
    """``"~3 s"``, ``"~2 min"``: an estimate's rounded text.

    >>> format_seconds(2.4), format_seconds(95)
    ('~2 s', '~2 min')
    """
    if seconds < 90:
        return f"~{max(1, round(seconds))} s"
    return f"~{round(seconds / 60)} min"


class SectionRunner:
    """Runs the sections of one report into ``doc`` / ``results`` (see the module's docstring).

    ``stream`` receives the plan line and, on a terminal (``progress=None``) or with ``progress=True``, the
    tqdm bar; ``stream=None`` prints nothing (library calls from Python by default print the plan only when
    asked). ``strict``: raise the first failure instead of boxing it.
    """

    def __init__(self, doc: Document, results: dict, *, stream: TextIO | None = None, progress: bool | None = None,
                 strict: bool = False, label: str = "report"):
        self.doc, self.results, self.stream, self.strict, self.label = doc, results, stream, strict, label
        self.progress = (stream is not None and hasattr(stream, "isatty") and stream.isatty()) \
            if progress is None else bool(progress)
        self.failures: list[SectionFailure] = []

    def plan_text(self, sections: list[Section]) -> str:
        """The line printed before the sections run: each section's estimate and the total."""
        total = sum(s.estimate_s for s in sections)
        parts = ", ".join(f"{s.label} {format_seconds(s.estimate_s)}" for s in sections)
        return f"{self.label}: {len(sections)} sections, estimated {format_seconds(total)} in all ({parts})"

    def run(self, sections: list[Section]) -> list[Any]:
        """Run ``sections`` in order; returns their return values (``None`` for a failed one)."""
        if self.stream is not None:
            print(self.plan_text(sections), file=self.stream, flush=True)
        out = []
        bar = tqdm(total=len(sections), disable=not self.progress, desc=self.label, unit="section",
                   file=self.stream or sys.stderr)
        with bar:
            for section in sections:
                bar.set_postfix_str(section.label, refresh=True)
                out.append(self.run_one(section))
                bar.update()
        return out

    def run_one(self, section: Section) -> Any:
        """Run one section; on any exception roll its blocks back and put a box in its place (:func:`reason_of`)."""
        doc = self.doc
        mark = (len(doc.blocks), doc._sections, doc._figures)
        t0 = time.perf_counter()
        try:
            value = section.run()
            self._timed(section, t0, True)
            return value
        except Exception as exc:   # noqa: BLE001 - any failure of one section is boxed, never fatal
            if self.strict:
                raise
            del doc.blocks[mark[0]:]
            doc._sections, doc._figures = mark[1], mark[2]
            reason = reason_of(exc)
            failure = SectionFailure(section.title, reason, type(exc).__name__)
            self.failures.append(failure)
            self.results.setdefault("failed_sections", []).append(failure.to_dict())
            self._timed(section, t0, False)
            if section.heading:
                doc.heading(section.title)
            doc.failure(section.title, reason, seconds=time.perf_counter() - t0)
            warnings.warn(f"report section '{section.title}' could not be computed ({reason}); the report was "
                          "written with a box in its place", SectionFailedWarning, stacklevel=2)
            return None

    def _timed(self, section: Section, t0: float, ok: bool) -> None:
        """Record the section's estimate and measured seconds in ``results["sections"]``."""
        self.results.setdefault("sections", []).append(
            {"section": section.label, "estimate_s": round(section.estimate_s, 2),
             "seconds": round(time.perf_counter() - t0, 2), "ok": ok})

