"""Benchmark: the cost of the default ``oed identify`` (the model chosen among OLS, WLS and the consistent fit,
:mod:`estimation.consistent.model_selection`) against ``--method ols``, this checkout against another revision.

Each command runs in a new process, as a user runs it (imports, reading, preparing, fitting, writing). Measured:
CPU time of the child (user + system, ``resource.getrusage(RUSAGE_CHILDREN)``: the steadier figure on a shared
machine) and wall time. The ratios are taken within one round of the same run: ``default / ols`` for each code,
``after / before`` for each command. The two codes run alternately (before-default, after-default, before-ols,
after-ols, round after round), so that a change of the machine's load falls on both.

``before`` is a revision of this repository (default ``main``) exported with ``git archive`` into a temporary folder
and put first on ``PYTHONPATH``; ``after`` is this checkout. The answers are compared: the chosen model and prior
weight must be equal, and the errors (the prior-weight search's validation errors, the candidates' scores, the
consistent fit's validation MSE) equal to a relative :data:`TOLERANCE` (IPOPT's ``tol`` is 1e-8 on the scaled
problem; measured differences 1e-11 to 5e-9).

Cases:

``kuka``
    KUKA LWR4+ (``../shared/data/kuka_lwr4``), trained on run 1, validated on run 2, with the logged ``dq``, ``ddq``
    (as ``bench_real_robots.py`` writes them), ``--friction viscous,coulomb,offset``;
``puma``
    the README's worked example: ``oed design`` (internal model, 2 starts) and ``oed simulate`` (seeds 1 and 2), then
    ``oed identify --robot puma560 --joints 3 --frequency 0.2 --harmonics 250 --average-periods no --held-torques``.

Run: ``PYTHONPATH=. python benchmarks/bench_identify_default.py [--cases kuka,puma] [--repeats 3] [--before main]``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
#: the relative difference allowed between the two codes' errors
TOLERANCE = 1e-6
RUN_OED = "import sys; from oed.cli import main; sys.exit(main())"


def oed(code: Path, arguments: list[str], cwd: Path) -> tuple[float, float]:
    """``oed ARGUMENTS`` in a new process with ``code`` first on the path: (CPU s, wall s)."""
    environment = {**os.environ, "PYTHONPATH": str(code)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    completed = subprocess.run([sys.executable, "-c", RUN_OED, *arguments], cwd=cwd, env=environment,
                               capture_output=True, text=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if completed.returncode != 0:
        raise RuntimeError(f"oed {' '.join(arguments)} failed ({code}):\n{completed.stderr[-2000:]}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def kuka_case(folder: Path) -> list[str]:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_real_robots import kuka  # the same files as the real-robot benchmark

    case = kuka(folder)
    return ["--urdf", str(DATA / "kuka_lwr4" / "kuka_lwr4.urdf"), "--data", str(case.files["train"]),
            "--validate", str(case.files["validate"]), "--friction", "viscous,coulomb,offset"]


def puma_case(folder: Path) -> list[str]:
    puma = ["--robot", "puma560", "--joints", "3"]
    oed(ROOT, ["design", *puma, "--model", "internal", "--starts", "2", "--out", "excitation.json"], folder)
    for seed, name in ((1, "train.csv"), (2, "validate.csv")):
        oed(ROOT, ["simulate", *puma, "--trajectory", "excitation.json", "--effects", "coulomb,offset", "--bandwidth",
                   "10", "--periods", "2", "--warmup-periods", "1", "--seed", str(seed), "--out", name], folder)
    return [*puma, "--data", str(folder / "train.csv"), "--validate", str(folder / "validate.csv"), "--frequency",
            "0.2", "--harmonics", "250", "--average-periods", "no", "--held-torques"]


def answers(path: Path) -> dict:
    document = json.loads(path.read_text())
    selection, consistent = document["model_selection"], document.get("consistent") or {}
    return {"chosen": selection["chosen"], "prior_weight": consistent.get("prior_weight"),
            "search": [entry["weighted_validation_error"] for entry in consistent.get("prior_weight_search", [])],
            "scores": [candidate["score"] for candidate in selection["candidates"]],
            "validation": list((consistent.get("validation") or {}).get("mse", {}).values())}


def compare(before: dict, after: dict) -> float:
    """The largest relative difference of the errors; the choices must be equal."""
    if before["chosen"] != after["chosen"] or before["prior_weight"] != after["prior_weight"]:
        raise AssertionError(f"the answers differ: {before['chosen']} at {before['prior_weight']} against "
                             f"{after['chosen']} at {after['prior_weight']}")
    differences = [abs(b - a) / abs(a) for key in ("search", "scores", "validation")
                   for a, b in zip(before[key], after[key])]
    return max(differences, default=0.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", default="kuka,puma")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--before", default="main", help="the revision compared with this checkout")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as temporary:
        temporary = Path(temporary)
        before_code = temporary / "before"
        before_code.mkdir()
        archive = subprocess.run(["git", "archive", args.before], cwd=ROOT, capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(before_code)], input=archive, check=True)
        codes = {"before": before_code, "after": ROOT}
        for name in args.cases.split(","):
            folder = temporary / name
            folder.mkdir()
            arguments = {"kuka": kuka_case, "puma": puma_case}[name](folder)
            times = {(code, method): [] for code in codes for method in ("default", "ols")}
            outputs = {}
            for _ in range(args.repeats):
                for method in ("default", "ols"):
                    for code, path in codes.items():
                        out = folder / f"{code}_{method}.json"
                        options = [] if method == "default" else ["--method", "ols"]
                        times[code, method].append(oed(path, ["identify", *arguments, *options, "--out", str(out)],
                                                       folder))
                        outputs[code, method] = out
            difference = compare(answers(outputs["before", "default"]), answers(outputs["after", "default"]))
            if difference > TOLERANCE:
                raise AssertionError(f"{name}: the errors differ by {difference:.3g} (relative)")
            chosen = answers(outputs["after", "default"])
            print(f"\n{name}: chosen {chosen['chosen']}, prior weight {chosen['prior_weight']} (both codes); "
                  f"largest relative difference of the errors {difference:.2g}")
            print("| code | default CPU s | default wall s | --method ols CPU s | ols wall s | default / ols CPU | "
                  "default / ols wall |")
            print("|---|---|---|---|---|---|---|")
            for code in codes:
                default, ols = np.array(times[code, "default"]), np.array(times[code, "ols"])
                print(f"| {code} | {_list(default[:, 0])} | {_list(default[:, 1])} | {_list(ols[:, 0])} | "
                      f"{_list(ols[:, 1])} | {_list(default[:, 0] / ols[:, 0], 'x')} | "
                      f"{_list(default[:, 1] / ols[:, 1], 'x')} |")
            after, before = np.array(times["after", "default"]), np.array(times["before", "default"])
            print(f"default after / before, round by round: CPU {_list(after[:, 0] / before[:, 0], 'x')}, "
                  f"wall {_list(after[:, 1] / before[:, 1], 'x')}")


def _list(values: np.ndarray, unit: str = "") -> str:
    return ", ".join(f"{value:.2f}{unit}" for value in values)


if __name__ == "__main__":
    main()
