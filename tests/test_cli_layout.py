"""The command line's modules: no verb imports another (what verbs share lives in shared modules)."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
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


def test_a_run_imports_its_own_verb_alone():
    # a fresh interpreter: the parser of one verb lists the others without importing their modules
    code = ("import sys, oed.cli; oed.cli.build_parser(('model',)); "
            "print(sorted(name for name in oed.cli.VERB_MODULES if 'oed.cli.' + name in sys.modules))")
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join([str(CLI.parents[1]), os.environ.get("PYTHONPATH", "")]))
    output = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=environment)
    assert output.stdout.strip() == "['model']"
