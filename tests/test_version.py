"""``oed --version``: the version of the installed distribution, which is ``oed.__version__``."""

from __future__ import annotations

import os
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

import oed
from oed.cli import DISTRIBUTION, main, package_version

ROOT = Path(__file__).resolve().parents[1]


def test_version_option_prints_the_package_version_and_exits_0(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"oed {package_version()}"


def test_the_console_entry_prints_the_version_as_one_line():
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-m", "oed", "--version"], capture_output=True, text=True, env=environment,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout == f"oed {oed.__version__}\n"


def test_installed_metadata_carries_the_version_written_in_oed():
    try:
        installed = metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        pytest.skip(f"{DISTRIBUTION} is not installed (the source tree runs uninstalled)")
    assert installed == oed.__version__ == package_version()


def test_without_an_installed_distribution_the_version_is_oed_dunder_version(monkeypatch):
    def missing(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "version", missing)
    assert package_version() == oed.__version__
