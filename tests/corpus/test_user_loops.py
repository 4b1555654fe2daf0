"""The loops a user runs on files, through the CLI: the README's (design, simulate twice, diagnose) and EMPS with
no flags. Each checks the effects named (:data:`tests.corpus.cases.README_LOOP`, ``EMPS_LOOP``), the final
validation error against the noise floor or the error before, and, where the truth is known, the estimates."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from estimation.datasets.shared import load_emps
from oed.cli import main
from tests.conftest import REPOSITORY, shared_data
from tests.corpus.cases import EMPS_LOOP, README_LOOP, SIGMAS, LoopCase
from tests.corpus.records import matches

pytestmark = pytest.mark.slow


def loop_marks(case: LoopCase) -> list[pytest.MarkDecorator]:
    return [pytest.mark.xfail(strict=True, reason=case.xfail)] if case.xfail else []


def named_in(report: dict) -> frozenset[tuple[str, str]]:
    return frozenset((effect["spec"], channel) for effect in report["effects"] for channel in effect["channels"])


def estimate_errors(report: dict, truth: dict[str, float]) -> dict[str, float]:
    """``|estimate − truth| / std`` of each true parameter the report names (linear and shape)."""
    errors = {}
    for effect in report["effects"]:
        pairs = list(zip(effect["parameters"], effect["values"], effect["std"]))
        pairs += [(name, value, effect["shape_std"].get(name, 0.0)) for name, value in effect["shape"].items()]
        for name, value, std in pairs:
            if name in truth:
                errors[name] = abs(value - truth[name]) / std if std > 0 else float("inf")
    return errors


def readme_truth(path: Path) -> dict[str, float]:
    """True values of the simulated effects (``--truth``), the Coulomb smoothing as the tanh law's ``vc``."""
    values: dict[str, float] = {}
    for effect in json.loads(path.read_text())["effects"]:
        values.update(effect["parameters"])
        if effect["name"] == "coulomb":
            values.update({f"vc{joint}": effect["settings"]["smoothing"] for joint in (1, 2, 3)})
    return values


def summary(report: dict, errors: dict[str, float]) -> str:
    found = ", ".join(sorted(f"{spec}@{channel}" for spec, channel in named_in(report)))
    validation = report["validation"]
    floor = validation["after"].get("mse_over_floor") or {}
    ratios = {channel: validation["after"]["mse"][channel] / validation["before"]["mse"][channel]
              for channel in validation["after"]["mse"]}
    worst = max(errors.items(), key=lambda item: item[1], default=("-", 0.0))
    return (f"named {found}; after/floor {'/'.join(f'{v:.2f}' for v in floor.values())}; after/before "
            f"{'/'.join(f'{v:.3g}' for v in ratios.values())}; worst estimate {worst[0]} {worst[1]:.1f} sd")


def check(case: LoopCase, report: dict, errors: dict[str, float]) -> None:
    text = summary(report, errors)
    print(f"\n{case.name}: {text}")
    assert any(matches(expected, named_in(report), case.allowed) for expected in (case.named, *case.also)), text
    validation = report["validation"]
    if case.floor_tolerance is not None:
        for channel, ratio in validation["after"]["mse_over_floor"].items():
            assert ratio <= case.floor_tolerance, (channel, text)
    if case.after_over_before is not None:
        for channel, after in validation["after"]["mse"].items():
            assert after <= case.after_over_before * validation["before"]["mse"][channel], (channel, text)
    for name, sigmas in errors.items():
        assert sigmas <= SIGMAS, (name, text)


@pytest.mark.parametrize("case", [pytest.param(README_LOOP, id="readme", marks=loop_marks(README_LOOP))])
def test_the_readme_loop(case, tmp_path):
    robot = ["--robot", "puma560", "--joints", "3"]
    trajectory, truth, report = tmp_path / "traj.json", tmp_path / "truth.json", tmp_path / "report.json"
    assert main(["design", *robot, "--model", "internal", "--starts", "2", "--seed", "1", "--quiet",
                 "--out", str(trajectory)]) == 0
    for seed, name in ((1, "r1.csv"), (2, "r2.csv")):
        assert main(["simulate", *robot, "--trajectory", str(trajectory), "--effects", "coulomb,offset", "--periods", "3",
                     "--warmup-periods", "1", "--seed", str(seed), "--truth", str(truth), "--out",
                     str(tmp_path / name)]) == 0
    assert main(["diagnose", *robot, "--model", "internal", "--data", str(tmp_path / "r1.csv"), "--validate",
                 str(tmp_path / "r2.csv"), "--out", str(report)]) == 0
    document = json.loads(report.read_text())
    check(case, document, estimate_errors(document, readme_truth(truth)))


def write_emps(which: str, path: Path) -> None:
    record = load_emps(shared_data("emps"), which)
    np.savetxt(path, np.column_stack([record.t, record.qm, record.force]), delimiter=",", header="t,q1,tau1",
               comments="")


@pytest.mark.realdata
@pytest.mark.parametrize("case", [pytest.param(EMPS_LOOP, id="emps", marks=loop_marks(EMPS_LOOP))])
def test_emps_without_flags(case, tmp_path):
    write_emps("estimation", tmp_path / "train.csv")
    write_emps("validation", tmp_path / "val.csv")
    report = tmp_path / "report.json"
    assert main(["diagnose", "--urdf", str(REPOSITORY / "dynamics" / "robots" / "emps.urdf"), "--model", "internal",
                 "--data", str(tmp_path / "train.csv"), "--validate", str(tmp_path / "val.csv"),
                 "--out", str(report)]) == 0
    check(case, json.loads(report.read_text()), {})
