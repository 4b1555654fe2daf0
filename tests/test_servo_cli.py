"""CLI round trip: oed aprbs -> oed servo-simulate -> oed servo-fit, with the promised columns and JSON keys."""

from __future__ import annotations

import json

import numpy as np
import pytest

from oed.cli import main

PROMISED_KEYS = {"b", "k", "sigma", "a1", "a2", "K", "rmse", "r2_adj", "r2_adj_free_run"}


def test_aprbs_simulate_fit_round_trip(tmp_path):
    aprbs, servo, fit = tmp_path / "aprbs.csv", tmp_path / "servo.csv", tmp_path / "fit.json"
    assert main(["aprbs", "--joints", "4", "--duration", "20", "--dt", "0.01", "--hold-min", "0.2", "--seed", "5", "--out", str(aprbs)]) == 0
    assert aprbs.read_text().splitlines()[0] == "t,u1,u2,u3,u4"
    assert main(["servo-simulate", "--aprbs", str(aprbs), "--out", str(servo), "--raw", "--seed", "1"]) == 0
    header = servo.read_text().splitlines()[0].split(",")
    assert header[:9] == ["t", "u1", "u2", "u3", "u4", "q1", "q2", "q3", "q4"]
    assert {f"gyro{j}" for j in range(1, 5)} | {f"acc_angle{j}" for j in range(1, 5)} <= set(header)
    for method in ("erls", "rls", "ls"):
        assert main(["servo-fit", "--data", str(servo), "--dt", "0.01", "--mass", "0.294,0.239,0.144,0.072", "--method", method, "--out", str(fit)]) == 0
        report = json.loads(fit.read_text())
        assert set(report["joints"]) == {"1", "2", "3", "4"}
        for joint in report["joints"].values():
            assert PROMISED_KEYS <= set(joint)
            assert all(np.isfinite(joint[key]) for key in PROMISED_KEYS)
            assert 0.5 < joint["r2_adj_free_run"] <= joint["r2_adj"] <= 1.0


def test_cli_errors_name_the_problem_and_leave_no_output(tmp_path, capsys):
    out = tmp_path / "a.csv"
    assert main(["aprbs", "--hold-min", "0.005", "--dt", "0.01", "--out", str(out)]) == 2
    assert "hold_min = 0.005 s is shorter than the sample time" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("t,u1,u2,u3,u4\n0,0,1,1.5,1\n0.01,0,1,1.5,1\n0.025,0,1,1.5,1\n0.035,0,1,1.5,1\n")
    assert main(["servo-simulate", "--aprbs", str(bad), "--out", str(out)]) == 2
    assert "time column 't' is not uniform" in capsys.readouterr().err
    bad.write_text("t,u1,u2,u3,u4\n0,0,1,1.5,1\n0.01,0,1,1.5,5.0\n0.02,0,1,1.5,1\n")
    assert main(["servo-simulate", "--aprbs", str(bad), "--out", str(out)]) == 2
    assert "column u4 = 5 rad at row 1 is above the upper joint-4 bound 4.5" in capsys.readouterr().err
    fit = tmp_path / "fit.json"
    assert main(["servo-fit", "--data", str(tmp_path / "missing.csv"), "--out", str(fit)]) == 2
    assert "not found" in capsys.readouterr().err
    assert not out.exists() and not fit.exists() and not list(tmp_path.glob(".*"))  # nor a staged temporary file


def test_servo_fit_checks_dt_against_the_time_column(tmp_path, capsys):
    data = tmp_path / "d.csv"
    t = np.arange(200) * 0.02
    np.savetxt(data, np.column_stack([t, np.sin(t), np.sin(t)]), delimiter=",", header="t,u1,q1", comments="")
    assert main(["servo-fit", "--data", str(data), "--dt", "0.01", "--out", str(tmp_path / "f.json")]) == 2
    assert "expected 0.01 s" in capsys.readouterr().err
    assert main(["servo-fit", "--data", str(data), "--dt", "-0.02", "--out", str(tmp_path / "f.json")]) == 2
    assert "dt must be positive and finite, got -0.02" in capsys.readouterr().err  # was: "'t' is not increasing"
    assert not (tmp_path / "f.json").exists()


@pytest.mark.parametrize("verb", ["aprbs", "servo-simulate", "servo-fit"])
def test_verbs_are_registered(verb, capsys):
    with pytest.raises(SystemExit):
        main([verb, "--help"])
    assert "usage: oed" in capsys.readouterr().out


def test_servo_fit_rejects_angles_in_degrees(tmp_path, capsys):
    t = np.arange(200) * 0.01
    u = np.sign(np.sin(t * 3))
    q = np.rad2deg(0.5 * np.sin(t * 3))  # ±28.6: degrees, not radians
    data = tmp_path / "degrees.csv"
    np.savetxt(data, np.column_stack([t, u, q]), delimiter=",", header="t,u1,q1", comments="")
    out = tmp_path / "fit.json"
    assert main(["servo-fit", "--data", str(data), "--mass", "0.3", "--out", str(out)]) == 2
    assert "q1 reaches 28.6" in capsys.readouterr().err and not out.exists()


def test_servo_csv_reader_takes_spreadsheet_headers_and_names_empty_files(tmp_path, capsys):
    from estimation.servo.files import read_csv

    path = tmp_path / "u.csv"
    path.write_text('\ufeff"t","u1"\n0,0.1\n0.01,0.2\n0.02,0.3\n', encoding="utf-8")  # BOM and quoted names
    table = read_csv(path, required=("t", "u1"))
    np.testing.assert_allclose(table.columns["u1"], [0.1, 0.2, 0.3])
    path.write_text("t,u1,u2,u3,u4\n")
    with pytest.raises(ValueError, match="a header but no data rows"):
        read_csv(path, required=("t", "u1"))
    assert main(["aprbs", "--duration", "5", "--out", str(tmp_path / "u.json")]) == 2
    assert "this verb writes CSV" in capsys.readouterr().err and not (tmp_path / "u.json").exists()
    assert main(["aprbs", "--duration", "5", "--candidates", "2", "--out", str(tmp_path / "plain")]) == 0
    assert (tmp_path / "plain").read_text().startswith("t,u1")  # no suffix: CSV, as before
