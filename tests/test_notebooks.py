"""The notebooks are executable documentation: each runs top to bottom and ends in checks.

They are stored without outputs; here they run in a fresh kernel from ``notebooks/`` (as a user
opening them would), writing their files to a temporary folder. A notebook that needs the real
data of ``../shared/data`` is skipped, saying why, when that folder is absent.
"""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

from tests.conftest import REPOSITORY, shared_data

NOTEBOOKS = REPOSITORY / "notebooks"
# notebook -> the shared data folder it needs (None: simulation only, or it skips that part itself)
CASES = {"puma_loop.ipynb": None, "servo_arm.ipynb": None, "emps.ipynb": "emps", "shaped_effects.ipynb": None,
         "model_export.ipynb": None, "sequential_design.ipynb": None, "payload.ipynb": None}


def _read(name: str) -> nbformat.NotebookNode:
    return nbformat.read(NOTEBOOKS / name, as_version=4)


def test_every_notebook_is_tested():
    assert sorted(path.name for path in NOTEBOOKS.glob("*.ipynb")) == sorted(CASES)


@pytest.mark.parametrize("name", sorted(CASES))
def test_notebook_is_stored_without_outputs(name: str):
    for cell in _read(name).cells:
        if cell.cell_type == "code":
            assert not cell.outputs and cell.execution_count is None, f"{name}: clear the outputs before committing"


@pytest.mark.parametrize("name", sorted(CASES))
def test_notebook_runs_and_its_checks_pass(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    if CASES[name] is not None:
        shared_data(CASES[name])
    monkeypatch.setenv("ROBOT_OED_NOTEBOOK_OUT", str(tmp_path))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    notebook = _read(name)
    client = NotebookClient(notebook, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(NOTEBOOKS)}})
    client.execute()  # raises CellExecutionError, with the cell and its traceback, when a check fails
    last = notebook.cells[-1]
    assert last.cell_type == "code" and "assert" in last.source, f"{name} must end in checks"
