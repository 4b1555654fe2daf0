"""Every verb's ``--help`` renders: argparse formats the help strings only when asked, so a stray ``%`` in one
is a crash that no other test meets."""

from __future__ import annotations

import pytest

from oed.cli import VERB_MODULES, build_parser


@pytest.mark.parametrize("verb", VERB_MODULES)
def test_every_verb_help_renders(verb: str, capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser()
    with pytest.raises(SystemExit) as stop:
        parser.parse_args([verb.replace("_", "-"), "--help"])
    assert stop.value.code == 0
    assert "usage: oed" in capsys.readouterr().out
