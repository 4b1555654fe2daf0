"""Warnings about input files, one line per finding: the same warning on several files (the same words, figures
aside) becomes one line naming how many files, said as soon as the files are read.

A reader warns per file (``"part3.csv: dropped 2 row(s) that repeat …"``); :func:`reading_findings` reads a set of
files, catches those warnings, and issues each finding once (``"31 files (a.csv, b.csv, c.csv and 28 more):
dropped 2 row(s) …"``), also as a progress line (:func:`dynamics.runtime.progress.report_warning`) so that a
command line shows it at once rather than at the end of the run. A run that reads its files in several passes (the
streamed path reads each file in blocks, two or three times) says each pass's findings as the pass ends, each
finding of a file once whatever the number of passes (:class:`FindingsSaid`).
"""

from __future__ import annotations

import contextlib
import re
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from dynamics.runtime.progress import report_warning

__all__ = ["Finding", "FindingsSaid", "group_findings", "grouped_messages", "reading_findings"]

#: files named in a grouped line before "and N more"
NAMED = 3
_CHUNK = re.compile(r"(?: \(rows [^)]*\))?: ")
_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


@dataclass
class Finding:
    """One warning text (``text``, without the file name) and the files (``sources``) that gave it; ``figures``:
    whether the files' texts differed in their figures (then ``text`` is the first file's)."""

    text: str
    category: type[Warning]
    sources: list[str] = field(default_factory=list)
    figures: bool = False

    def message(self) -> str:
        """The line said: the text after the file name, or after how many files and which."""
        if len(self.sources) == 1:
            return f"{self.sources[0]}: {self.text}"
        names = [Path(source).name for source in self.sources]
        listed = ", ".join(names[:NAMED]) + (f" and {len(names) - NAMED} more" if len(names) > NAMED else "")
        figures = f" (figures of {names[0]}; the others' differ)" if self.figures else ""
        return f"{len(self.sources)} files ({listed}): {self.text}{figures}"

    def key(self) -> tuple[object, ...]:
        """What makes two warnings one finding: the category and the words, figures aside (a warning naming no
        file: its whole text)."""
        return (self.category, _NUMBER.sub("#", self.text)) if self.sources else ("as is", self.text)


def group_findings(caught: Sequence[warnings.WarningMessage], sources: Sequence[str]) -> list[Finding]:
    """The warnings ``caught`` while reading ``sources``, one :class:`Finding` per text (figures aside), in the
    order first seen; a warning that names none of the sources is kept as it is (once)."""
    by_key: dict[tuple[object, ...], Finding] = {}
    for warning in caught:
        message = str(warning.message)
        source, text = _split(message, sources)
        if source is None:
            by_key.setdefault(("as is", message), Finding(message, warning.category, []))
            continue
        finding = by_key.setdefault((warning.category, _NUMBER.sub("#", text)), Finding(text, warning.category))
        if source not in finding.sources:
            finding.sources.append(source)
            finding.figures |= text != finding.text
    return list(by_key.values())


def _split(message: str, sources: Sequence[str]) -> tuple[str | None, str]:
    """The source a message names first (``path: …``, or ``path (rows a-b): …`` of a chunk) and the rest."""
    for source in sorted(sources, key=len, reverse=True):
        if message.startswith(source):
            after = _CHUNK.match(message, len(source))
            if after is not None:
                return source, message[after.end():]
    return None, message


def _said(finding: Finding) -> str:
    return finding.message() if finding.sources else finding.text


def grouped_messages(caught: Sequence[warnings.WarningMessage], sources: Sequence[object]) -> list[str]:
    """The lines of :func:`group_findings` (for a run that reads its files in passes, said at its end)."""
    return [_said(finding) for finding in group_findings(caught, [str(source) for source in sources])]


@contextlib.contextmanager
def reading_findings(sources: Sequence[object]) -> Iterator[None]:
    """Within the block (the files ``sources`` being read), the readers' warnings are held; at its end each finding
    is issued once (:func:`group_findings`), as a warning of its category and as a progress line. An error in the
    block drops them: the error is what is said."""
    with FindingsSaid(sources).reading():
        yield


class FindingsSaid:
    """The findings of files read in several passes (the streamed path reads each file in blocks, two or three
    times): within each :meth:`reading` block the readers' warnings are held, and at its end each finding not said
    before is said (a warning of its category and a progress line), naming the files that gave it in that pass and
    not before; a finding a later pass finds again in the same file is not said again. One object a run: it holds
    what that run has said.

    ::

        findings = FindingsSaid([*train, *validate])
        with findings.reading():
            first = subsample_pass(...)     # "3 files (a.csv, b.csv, c.csv): dropped 2 row(s) …", said here
        with findings.reading():
            sums = sums_pass(...)           # the same in a, b, c: nothing; in the validation file: said
    """

    def __init__(self, sources: Sequence[object]) -> None:
        self.sources = [str(source) for source in sources]
        self.lines: list[str] = []
        self._said: dict[tuple[object, ...], set[str]] = {}

    @contextlib.contextmanager
    def reading(self) -> Iterator[None]:
        """Hold the warnings of the block; at its end say the findings new to this run (an error in the block
        drops them: the error is what is said)."""
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield
        for finding in self._new(caught):
            line = _said(finding)
            self.lines.append(line)
            report_warning(line)
            warnings.warn(line, finding.category, stacklevel=3)

    def mark(self, caught: Sequence[warnings.WarningMessage]) -> list[str]:
        """Take the findings of ``caught`` as said (by the caller, e.g. before the run chose its path); returns
        their lines (those new to this run)."""
        return [_said(finding) for finding in self._new(caught)]

    def _new(self, caught: Sequence[warnings.WarningMessage]) -> list[Finding]:
        """The findings of ``caught`` new to this run, or from files that had not given them, now taken as said."""
        fresh = []
        for warning in caught:
            message = str(warning.message)
            source, text = _split(message, self.sources)
            key = ("as is", message) if source is None else (warning.category, _NUMBER.sub("#", text))
            if key not in self._said or (source is not None and source not in self._said[key]):
                fresh.append(warning)
        findings = group_findings(fresh, self.sources)
        for finding in findings:
            self._said.setdefault(finding.key(), set()).update(finding.sources)
        return findings
