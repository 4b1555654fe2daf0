"""A run of one verb registers (and imports) that verb alone; help, a version request or a misspelt verb
lists every verb from the table of verbs, so that argparse names them all."""

from __future__ import annotations

import ast
import subprocess
import sys

import pytest

from oed.cli import VERB_MODULES, main, requested_verb


@pytest.mark.parametrize("argv, expected", [
    (["design", "--out", "x.json"], "design"),
    (["servo-fit", "--help"], "servo-fit"),
    (["--help"], None),
    ([], None),
    (["desing"], "desing"),
])
def test_the_verb_is_the_first_word_that_is_not_an_option(argv, expected):
    assert requested_verb(argv) == expected


def test_a_misspelt_verb_is_refused_with_every_verb_listed(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["desing"])
    assert stop.value.code == 2
    error = capsys.readouterr().err
    assert "invalid choice: 'desing'" in error and "servo-fit" in error and "diagnose" in error


def test_a_design_run_imports_no_other_verb():
    code = ("import sys\nfrom oed.cli import main\n"
            "try:\n    main(['design', '--help'])\nexcept SystemExit:\n    pass\n"
            "print(sorted(name for name in sys.modules if name.startswith('oed.cli.') and name.count('.') == 2))")
    shown = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    loaded = ast.literal_eval(shown.strip().splitlines()[-1])
    verbs = {f"oed.cli.{name}" for name in VERB_MODULES}
    assert set(loaded) & verbs == {"oed.cli.design"}
