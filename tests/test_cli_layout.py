"""The command line's modules: no verb imports another (what verbs share lives in shared modules)."""

from __future__ import annotations

import ast
from pathlib import Path

import oed.cli
from oed.cli import VERB_MODULES

CLI = Path(oed.cli.__file__).parent


def imported_cli_modules(path: Path) -> set[str]:
    """The ``oed.cli`` modules ``path`` imports, anywhere in it (``oed.cli.NAME`` -> ``NAME``)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("oed.cli."):
            names.add(node.module.removeprefix("oed.cli.").split(".")[0])
        elif isinstance(node, ast.Import):
            names.update(alias.name.removeprefix("oed.cli.").split(".")[0] for alias in node.names
                         if alias.name.startswith("oed.cli."))
    return names


def test_no_cli_module_imports_a_verb():
    offenders = {path.stem: sorted(imported_cli_modules(path) & set(VERB_MODULES))
                 for path in sorted(CLI.glob("*.py"))}
    assert {module: verbs for module, verbs in offenders.items() if verbs} == {}
