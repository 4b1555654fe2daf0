"""Every code block of README.md and docs/**/*.md runs, so the documentation cannot drift from the code.

Fenced blocks are taken by their language:

- ``python``: executed with this interpreter; the blocks of one page run in order in one namespace, so a
  later block may use the names an earlier one defined;
- ``bash``, ``sh``, ``console``: each line (``\\`` continues it, ``#`` starts a comment, a ``$ `` prompt
  is dropped) must be an ``oed …`` command. The first documented command of each verb (pages in the order
  of :func:`documentation_pages`) runs as ``python -m oed …`` in a fresh interpreter, as a user types it;
  the later ones call ``oed.cli.main`` in this process with the same arguments (the same parser, the same
  exit codes, without an interpreter's start-up and imports a command);
- ``text``, ``json``, ``yaml``, ``toml``, ``csv``, ``markdown``: output or file contents, not executed.

Each page runs in a temporary folder of its own, its blocks in document order, so the files one command
writes feed the next command or Python block. A failure names the page and the line of the block.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import traceback
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass
from functools import cache
from io import StringIO
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PYTHON_LANGUAGES = frozenset({"python", "py"})
SHELL_LANGUAGES = frozenset({"bash", "sh", "console"})
SHOWN_LANGUAGES = frozenset({"text", "json", "yaml", "toml", "csv", "markdown"})
#: seconds one ``oed`` command of a snippet may take before the test gives up on it
COMMAND_TIMEOUT = 300
FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})\s*(?P<info>[^`]*)$")


class SnippetError(AssertionError):
    """A code block of the documentation that fails, named by page and line."""


@dataclass(frozen=True)
class Block:
    """One fenced code block: where it starts (1-based line of its opening fence), its language and text."""

    page: Path
    line: int
    language: str
    text: str

    @property
    def where(self) -> str:
        """``page:line`` relative to the repository when possible."""
        try:
            page = self.page.relative_to(ROOT)
        except ValueError:
            page = self.page
        return f"{page}:{self.line}"


def fenced_blocks(page: Path) -> list[Block]:
    """Return the fenced code blocks of a Markdown page in document order (indented fences included)."""
    blocks: list[Block] = []
    lines = page.read_text(encoding="utf-8").splitlines()
    index = 0
    while index < len(lines):
        opening = FENCE.match(lines[index])
        if opening is None:
            index += 1
            continue
        indent, fence, opening_line = opening["indent"], opening["fence"], index + 1
        language = opening["info"].strip().split(" ")[0].strip("{}.").lower()
        body: list[str] = []
        index += 1
        while index < len(lines):
            line = lines[index]
            if line.strip().startswith(fence[0] * len(fence)) and not line.strip().strip(fence[0]):
                break
            body.append(line[len(indent):] if line.startswith(indent) else line.lstrip())
            index += 1
        else:
            raise SnippetError(f"{page}:{opening_line}: a code block is never closed")
        blocks.append(Block(page=page, line=opening_line, language=language, text="\n".join(body) + "\n"))
        index += 1
    return blocks


def shell_commands(block: Block) -> list[tuple[int, list[str]]]:
    """Return ``(line, arguments after 'oed')`` for each command of a shell block; anything else is an error."""
    commands: list[tuple[int, list[str]]] = []
    pending, first_line = "", 0
    for offset, raw in enumerate(block.text.splitlines(), start=1):
        line = raw[2:] if raw.startswith("$ ") else raw
        if not pending:
            first_line = block.line + offset
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        words = shlex.split(pending + line, comments=True)
        pending = ""
        if not words:
            continue
        if words[0] != "oed":
            raise SnippetError(
                f"{block.page}:{first_line}: {words[0]!r} is not an `oed` command: a {block.language} block may hold "
                "only `oed …` commands (show other commands in a ```text block)"
            )
        commands.append((first_line, words[1:]))
    return commands


def run_python(block: Block, namespace: dict) -> None:
    """Execute a Python block in the page's namespace; tracebacks carry the page's own line numbers."""
    code = compile("\n" * block.line + block.text, block.where.rsplit(":", 1)[0], "exec")
    try:
        exec(code, namespace)
    except Exception as error:  # the snippet's own failure, reported with its place in the page
        raise SnippetError(f"{block.where}: python block failed:\n{traceback.format_exc()}") from error


def verb_of(arguments: list[str]) -> str | None:
    """The verb of an ``oed`` command line (its first word that is not an option)."""
    return next((word for word in arguments if not word.startswith("-")), None)


@cache
def first_commands() -> frozenset[tuple[str, int]]:
    """``(page, line)`` of the first documented command of each verb: these run in a fresh interpreter."""
    first: dict[str | None, tuple[str, int]] = {}
    for page in documentation_pages():
        for block in fenced_blocks(page):
            if block.language in SHELL_LANGUAGES:
                for line, arguments in shell_commands(block):
                    first.setdefault(verb_of(arguments), (str(page), line))
    return frozenset(first.values())


def run_subprocess(arguments: list[str], folder: Path) -> tuple[int, str]:
    """``python -m oed …`` in ``folder``: its exit code and standard error."""
    environment = dict(os.environ, MPLBACKEND="Agg")
    environment["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    completed = subprocess.run(
        [sys.executable, "-m", "oed", *arguments], cwd=folder, env=environment,
        capture_output=True, text=True, timeout=COMMAND_TIMEOUT,
    )
    return completed.returncode, completed.stderr


def run_in_process(arguments: list[str], folder: Path) -> tuple[int, str]:
    """``oed.cli.main(arguments)`` with ``folder`` as working directory: its exit code and standard error."""
    from oed.cli import main

    previous, stdout, stderr = Path.cwd(), StringIO(), StringIO()
    os.chdir(folder)
    try:
        with redirect_stdout(stdout), redirect_stderr(stderr):
            try:
                code = main(arguments)
            except SystemExit as exit_:  # argparse's usage errors
                code = exit_.code if isinstance(exit_.code, int) else int(exit_.code is not None)
    finally:
        os.chdir(previous)
    return code, stderr.getvalue()


def run_shell(block: Block, folder: Path, subprocess_lines: frozenset[int] | None = None) -> None:
    """Run each ``oed`` command of a shell block in ``folder``; a non-zero exit fails.

    Commands whose line is in ``subprocess_lines`` (all of them when it is ``None``) run as ``python -m oed``,
    the others in this process (:func:`run_in_process`).
    """
    for line, arguments in shell_commands(block):
        fresh = subprocess_lines is None or line in subprocess_lines
        code, stderr = (run_subprocess if fresh else run_in_process)(arguments, folder)
        if code != 0:
            raise SnippetError(
                f"{block.page.name}:{line} ({block.where}): `oed {shlex.join(arguments)}` exited with "
                f"{code}:\n{stderr[-3000:]}"
            )


def run_page(page: Path, folder: Path, in_process: bool = False) -> int:
    """Run every executable block of ``page`` in order inside ``folder``; return how many ran.

    With ``in_process``, the ``oed`` commands run in this process except the first documented one of each
    verb (:func:`first_commands`); without, every command runs as ``python -m oed``.
    """
    subprocess_lines = (frozenset(line for where, line in first_commands() if where == str(page))
                        if in_process else None)
    namespace: dict = {"__name__": "__doc_snippet__"}
    executed = 0
    previous = Path.cwd()
    os.chdir(folder)
    try:
        for block in fenced_blocks(page):
            if block.language in PYTHON_LANGUAGES:
                run_python(block, namespace)
            elif block.language in SHELL_LANGUAGES:
                run_shell(block, folder, subprocess_lines)
            elif block.language in SHOWN_LANGUAGES:
                continue
            else:
                raise SnippetError(
                    f"{block.where}: code block language {block.language or '(none)'!r}: use python or bash "
                    f"(executed) or one of {sorted(SHOWN_LANGUAGES)} (shown only)"
                )
            executed += 1
    finally:
        os.chdir(previous)
    return executed


def documentation_pages() -> list[Path]:
    """README.md and every Markdown page under docs/."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


@pytest.mark.parametrize("page", documentation_pages(), ids=lambda page: str(page.relative_to(ROOT)))
def test_page_snippets_run(page: Path, tmp_path: Path) -> None:
    run_page(page, tmp_path, in_process=True)


def test_readme_has_snippets() -> None:
    """The README's worked example is executed, not merely skipped."""
    languages = [block.language for block in fenced_blocks(ROOT / "README.md")]
    assert sum(language in SHELL_LANGUAGES for language in languages) >= 2
    assert sum(language in PYTHON_LANGUAGES for language in languages) >= 1


def test_a_broken_python_snippet_fails_with_its_place(tmp_path: Path) -> None:
    page = tmp_path / "broken.md"
    page.write_text("# Title\n\n```python\nvalue = 1\n```\n\ntext\n\n```python\nprint(undefined_name)\n```\n")
    with pytest.raises(SnippetError, match=r"broken\.md:9: python block failed(.|\n)*undefined_name"):
        run_page(page, tmp_path)


def test_a_failing_command_fails_with_its_place(tmp_path: Path) -> None:
    page = tmp_path / "broken.md"
    page.write_text("Text\n\n```bash\noed model --robot no_such_robot \\\n    --joints 3\n```\n")
    with pytest.raises(SnippetError, match=r"broken\.md:4 .*exited with 2"):
        run_page(page, tmp_path)
    with pytest.raises(SnippetError, match=r"broken\.md:4 .*exited with 2(.|\n)*no_such_robot"):
        run_page(page, tmp_path, in_process=True)  # the command in this process fails alike, its message kept
    page.write_text("```bash\noed simulate --robot puma560 --joints 3 --trajectory missing.json --out r.csv\n```\n")
    with pytest.raises(SnippetError, match=r"broken\.md:2 .*exited with 2(.|\n)*not found: missing\.json"):
        run_page(page, tmp_path, in_process=True)


def test_the_first_command_of_each_verb_runs_in_a_fresh_interpreter() -> None:
    """Every documented verb keeps one real ``python -m oed`` run (start-up, imports, exit code)."""
    verbs = {verb_of(arguments) for page in documentation_pages() for block in fenced_blocks(page)
             if block.language in SHELL_LANGUAGES for _, arguments in shell_commands(block)}
    assert len(first_commands()) == len(verbs) >= 10
    assert (str(ROOT / "README.md"), 64) in first_commands()  # `oed model`, the README's first command


def test_a_shell_block_holds_only_oed_commands(tmp_path: Path) -> None:
    page = tmp_path / "other.md"
    page.write_text("```sh\n# set-up\nmake test\n```\n")
    with pytest.raises(SnippetError, match=r"other\.md:3: 'make' is not an `oed` command"):
        run_page(page, tmp_path)


def test_an_unmarked_block_is_refused(tmp_path: Path) -> None:
    page = tmp_path / "plain.md"
    page.write_text("```\nsomething\n```\n")
    with pytest.raises(SnippetError, match=r"plain\.md:1: code block language '\(none\)'"):
        run_page(page, tmp_path)
