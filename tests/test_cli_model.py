"""``oed model``: JSON document and readable table; errors as messages with exit code 2."""

from __future__ import annotations

import json

from oed.cli import main


def test_model_json_has_the_promised_keys(capsys):
    assert main(["model", "--robot", "puma560", "--joints", "3", "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert set(document) >= {"internal", "external", "combined"}
    assert document["internal"]["n_base"] == 18
    assert document["combined"]["n_base"] == 23
    parameter = document["internal"]["parameters"][0]
    assert set(parameter) >= {"name", "expression"}


def test_model_table_with_friction_list(capsys):
    assert main(["model", "--robot", "puma560", "--joints", "3", "--friction", "viscous,coulomb,offset,armature"]) == 0
    out = capsys.readouterr().out
    # 18 + 3 Coulomb + 3 offsets + 3 armatures, less Ia1 and Ia2 which the inertias of the
    # links about the joint-1 and joint-2 axes absorb
    assert "internal model: 25 base parameters" in out
    assert "Izz2R  = Izz2 - a2**2*(m2 + m3) + Ia2" in out
    assert "fc3" in out


def test_model_with_urdf(capsys, prismatic_urdf):
    assert main(["model", "--urdf", str(prismatic_urdf), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["internal"]["n_base"] > 0


def test_unknown_robot_is_a_message_and_exit_code_2(capsys):
    assert main(["model", "--robot", "nope"]) == 2
    assert "unknown robot 'nope'" in capsys.readouterr().err


def test_unknown_friction_is_a_message(capsys):
    assert main(["model", "--friction", "viscous,magic"]) == 2
    assert "unknown effect 'magic'" in capsys.readouterr().err


def test_an_unexpected_exception_is_one_line_with_exit_code_1(monkeypatch, capsys):
    import oed.cli.model

    def broken(args):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(oed.cli.model, "run", broken)
    monkeypatch.delenv("OED_TRACEBACK", raising=False)
    assert main(["model", "--joints", "3"]) == 1
    error = capsys.readouterr().err
    assert error.startswith("oed model: internal error: ZeroDivisionError: division by zero")
    assert "Traceback" not in error
