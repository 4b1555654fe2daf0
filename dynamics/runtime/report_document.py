"""A report a person reads, built once and written as Markdown (figures as PNG files beside it) or as one
self-contained HTML file (figures inline as base64 PNG).

A :class:`Report` is a title and a sequence of blocks (:class:`Heading`, :class:`Paragraph`, :class:`Bullets`,
:class:`Table`, :class:`Figure`); a verb builds it in one place, and :meth:`Report.markdown` and
:meth:`Report.html` only render it, so both documents hold the same text, tables and figures::

    report = Report("Diagnosis", (Paragraph("Declared effects: `viscous`."), Table(("channel", "MSE"), rows)))
    report.write(path, outputs)       # the suffix chooses: .md (figures beside it) or .html (figures inline)

Text is plain with `code` spans in backticks (escaped for HTML).
"""

from __future__ import annotations

import base64
import html
import io
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from dynamics.runtime.output_files import save_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure as MatplotlibFigure

    from dynamics.runtime.output_files import OutputFiles

__all__ = ["Block", "Bullets", "Figure", "Heading", "HTML_SUFFIXES", "MARKDOWN_SUFFIXES", "Paragraph", "Report", "Table",
           "figure_path", "report_format"]

#: suffixes of a Markdown report and of an HTML report
MARKDOWN_SUFFIXES = frozenset({".md", ".markdown"})
HTML_SUFFIXES = frozenset({".html", ".htm"})
#: resolution of the figures (both formats)
DPI = 90


@dataclass(frozen=True)
class Heading:
    """A section title (``level`` 2 for a section, 3 for a subsection)."""

    text: str
    level: int = 2


@dataclass(frozen=True)
class Paragraph:
    """A paragraph of plain text (backticks mark code)."""

    text: str


@dataclass(frozen=True)
class Bullets:
    """A list of plain-text items."""

    items: tuple[str, ...]


@dataclass(frozen=True)
class Table:
    """A table of text cells (numbers formatted by the builder)."""

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]


@dataclass(frozen=True)
class Figure:
    """A figure drawn on demand: ``name`` names its file beside a Markdown report (``report.<name>.png``),
    ``caption`` is its alternative text and caption, ``draw`` returns a matplotlib figure."""

    name: str
    caption: str
    draw: Callable[[], MatplotlibFigure]


Block = Heading | Paragraph | Bullets | Table | Figure


def report_format(path: str | Path) -> str:
    """``"markdown"`` or ``"html"`` from the suffix of ``path``; a ValueError for another suffix."""
    suffix = Path(path).suffix.lower()
    if suffix in MARKDOWN_SUFFIXES:
        return "markdown"
    if suffix in HTML_SUFFIXES:
        return "html"
    raise ValueError(f"{path}: a report is Markdown (.md) or HTML (.html)")


def figure_path(report: str | Path, name: str) -> Path:
    """The PNG file of figure ``name`` beside the Markdown report ``report``."""
    return Path(report).with_suffix(f".{name}.png")


_CODE = re.compile(r"`([^`]*)`")
_NUMBER = re.compile(r"^[-+]?(\d|\.\d|nan|inf)[\d.e+\-]* ?%?$")


def _inline_html(text: str) -> str:
    parts = _CODE.split(text)
    return "".join(f"<code>{html.escape(part)}</code>" if index % 2 else html.escape(part)
                   for index, part in enumerate(parts))


def _markdown_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


@dataclass(frozen=True)
class Report:
    """A titled sequence of blocks (module docstring)."""

    title: str
    blocks: tuple[Block, ...]

    def figures(self) -> tuple[Figure, ...]:
        """The figures, in order."""
        return tuple(block for block in self.blocks if isinstance(block, Figure))

    def tables(self) -> tuple[Table, ...]:
        """The tables, in order."""
        return tuple(block for block in self.blocks if isinstance(block, Table))

    def markdown(self, figure_files: Callable[[Figure], str] | None = None) -> str:
        """The Markdown document; a figure is linked as ``figure_files(figure)`` (default: ``<name>.png``)."""
        def link(figure: Figure) -> str:
            return figure_files(figure) if figure_files is not None else f"{figure.name}.png"

        lines = [f"# {self.title}"]
        for block in self.blocks:
            lines.append("")
            if isinstance(block, Heading):
                lines.append("#" * block.level + " " + block.text)
            elif isinstance(block, Paragraph):
                lines.append(block.text)
            elif isinstance(block, Bullets):
                lines += [f"- {item}" for item in block.items]
            elif isinstance(block, Table):
                lines.append("| " + " | ".join(_markdown_cell(cell) for cell in block.header) + " |")
                lines.append("|" + "---|" * len(block.header))
                lines += ["| " + " | ".join(_markdown_cell(cell) for cell in row) + " |" for row in block.rows]
            else:
                lines.append(f"![{block.caption}]({link(block)})")
        return "\n".join(lines) + "\n"

    def html(self) -> str:
        """One self-contained HTML document: every figure drawn and inlined as a base64 PNG."""
        body = [f"<h1>{_inline_html(self.title)}</h1>"]
        for block in self.blocks:
            if isinstance(block, Heading):
                body.append(f"<h{block.level}>{_inline_html(block.text)}</h{block.level}>")
            elif isinstance(block, Paragraph):
                body.append(f"<p>{_inline_html(block.text)}</p>")
            elif isinstance(block, Bullets):
                body.append("<ul>" + "".join(f"<li>{_inline_html(item)}</li>" for item in block.items) + "</ul>")
            elif isinstance(block, Table):
                head = "".join(f"<th>{_inline_html(cell)}</th>" for cell in block.header)
                rows = "".join("<tr>" + "".join(f'<td class="n">{_inline_html(cell)}</td>' if _NUMBER.match(cell)
                                                else f"<td>{_inline_html(cell)}</td>" for cell in row) + "</tr>"
                               for row in block.rows)
                body.append(f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>")
            else:
                encoded = base64.b64encode(png_bytes(block.draw())).decode("ascii")
                caption = _inline_html(block.caption)
                body.append(f'<figure><img alt="{html.escape(block.caption)}" '
                            f'src="data:image/png;base64,{encoded}"><figcaption>{caption}</figcaption></figure>')
        return (f"<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
                f"<title>{html.escape(self.title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
                + "\n".join(body) + "\n</body>\n</html>\n")

    def write(self, path: str | Path, outputs: OutputFiles) -> tuple[Path, ...]:
        """Write the report at ``path`` through ``outputs`` (all files or none): Markdown with each figure as
        :func:`figure_path` beside it, or HTML with the figures inline, by the suffix. Returns the files written."""
        kind = report_format(path)
        if kind == "html":
            with outputs.open(path) as stream:
                stream.write(self.html())
            return (Path(path),)
        written = []
        for figure in self.figures():
            target = figure_path(path, figure.name)
            save_figure(figure.draw(), outputs.stage_figure(target), dpi=DPI)
            written.append(target)
        with outputs.open(path) as stream:
            stream.write(self.markdown(lambda figure: figure_path(path, figure.name).name))
        return (*written, Path(path))


def png_bytes(figure: MatplotlibFigure) -> bytes:
    """``figure`` as PNG bytes."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI)
    return buffer.getvalue()


_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 72rem; margin: 2rem auto; padding: 0 1rem; color: #222; }
table { border-collapse: collapse; margin: 0.5rem 0 1rem; font-size: 0.9rem; }
th, td { border: 1px solid #ccc; padding: 0.2rem 0.6rem; text-align: left; vertical-align: top; }
th { background: #f2f2f2; } td.n { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1rem 0; } img { max-width: 100%; } figcaption { font-size: 0.85rem; color: #555; }
code { background: #f4f4f4; padding: 0 0.2rem; }
""".strip()
