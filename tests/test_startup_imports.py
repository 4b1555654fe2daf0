"""What the command line imports before it works: each module a run imports is compiled (without cached bytecode)
and executed, whether the run uses it or not. ``oed --help`` imports none of the numerical libraries; ``oed
diagnose`` imports neither the streamed path's modules nor the report's when it runs in memory without
``--report`` (they are imported where they are used)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: the libraries no top-level ``oed --help`` (nor ``--version``) needs
HEAVY = ("numpy", "scipy", "pandas", "casadi", "pinocchio", "matplotlib", "pyarrow")


def imported_after(code: str) -> set[str]:
    """The modules a fresh interpreter holds after running ``code`` (this checkout first on the path)."""
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    script = f"{code}\nimport sys\nprint('MODULES', *sorted(sys.modules))"
    output = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                            env=environment, cwd=ROOT).stdout
    line = next(line for line in output.splitlines() if line.startswith("MODULES "))
    return set(line.split()[1:])


def command_line(*arguments: str) -> str:
    """Code that runs ``python -m oed ARGUMENTS`` as the console script does, its exit caught."""
    return (f"import runpy, sys\nsys.argv = ['oed', *{list(arguments)!r}]\n"
            "try:\n    runpy.run_module('oed', run_name='__main__')\nexcept SystemExit:\n    pass")


def heavy(modules: set[str]) -> list[str]:
    return sorted(name for name in modules if name.split(".")[0] in HEAVY)


def test_oed_help_and_version_import_no_numerical_library():
    for arguments in (("--help",), ("--version",)):
        assert heavy(imported_after(command_line(*arguments))) == [], arguments


def test_the_diagnose_verb_imports_neither_the_streamed_path_nor_the_report():
    modules = imported_after("import oed.cli\noed.cli.build_parser(('diagnose',))")
    assert "oed.workflows.diagnose" in modules  # the verb's own work is imported (the check below can fail)
    streamed = sorted(name for name in modules if name.startswith("estimation.streaming.")
                      and name != "estimation.streaming.settings")
    assert streamed == []
    assert not {"estimation.diagnosis.report", "estimation.identification.report"} & modules
    assert not [name for name in modules if name.split(".")[0] == "matplotlib"]


def test_the_settings_named_before_streaming_are_those_of_the_streamed_path():
    import estimation.streaming as streaming
    from estimation.streaming import cluster, diagnosis, diagnosis_passes, settings

    assert diagnosis.DEFAULT_SUBSAMPLE == settings.DEFAULT_SUBSAMPLE == streaming.DEFAULT_SUBSAMPLE
    assert diagnosis_passes.FLOOR_WINDOW == settings.FLOOR_WINDOW == streaming.FLOOR_WINDOW
    assert cluster.SCHEDULER_VARIABLE == settings.SCHEDULER_VARIABLE == streaming.SCHEDULER_VARIABLE
    assert cluster.scheduler_address is settings.scheduler_address is streaming.scheduler_address
