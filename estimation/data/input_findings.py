"""Warnings about input files, one line per finding: the same warning on several files (the same words, figures
aside) becomes one line naming how many files, said as soon as the files are read.

A reader warns per file (``"part3.csv: dropped 2 row(s) that repeat …"``); :func:`reading_findings` reads a set of
files, catches those warnings, and issues each finding once (``"31 files (a.csv, b.csv, c.csv and 28 more):
dropped 2 row(s) …"``), also as a progress line (:func:`dynamics.runtime.progress.report_warning`) so that a
command line shows it at once rather than at the end of the run.
"""

from __future__ import annotations

import contextlib
import re
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from dynamics.runtime.progress import report_warning

__all__ = ["Finding", "group_findings", "grouped_messages", "reading_findings"]

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
    names = [str(source) for source in sources]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    for finding in group_findings(caught, names):
        line = _said(finding)
        report_warning(line)
        warnings.warn(line, finding.category, stacklevel=3)
