"""Benchmark (issue 34, h-shortval2): where the test error of a model identified on short records comes from.

For one robot's records degraded as :mod:`benchmarks.bench_real_degraded` degrades them (default: the Panda's records
cut short, training 4.6 s and validation 2 s), the default ``oed identify`` is run, then ``oed predict`` with each
candidate the result file holds (``--alternative ols|wls|consistent``) on the training, validation and test files:

* each candidate's test MSE per joint over the plain least-squares fit's on the same recorded samples (as
  :func:`benchmarks.bench_real_degraded.compare_degraded` scores the verbs);
* each candidate's **predicted parameter variance** on each record: the mean over the samples of the 95 % band's
  variance (``((hi - lo) / 2 / 1.96)²``, that is ``y_bᵀ Σ_θ y_b + σ_c²``), summed over the joints. Its noise term
  ``σ_c²`` is the same on every record, so the differences between records are the parameter term's alone: a test
  record whose variance exceeds the training record's excites directions the training record left undetermined, and
  a validation record whose variance equals the training record's measured nothing of them.

Run: ``python benchmarks/bench_short_records.py [--robot panda] [--degradation short]``
(``--degradation none``: the records as they are).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.bench_real_degraded import DEGRADATIONS, at_recorded, degraded_case, resent, run_logged, run_verb
from benchmarks.bench_real_robots import ROBOTS, PlainFit

#: the two-sided 95 % quantile of the band ``oed predict`` writes
Z95 = 1.959964


def band_variance(table: pd.DataFrame, channels: list[str]) -> float:
    """The mean over the samples of the prediction band's variance, summed over ``channels``."""
    return float(sum(np.mean(((table[f"{c}_hi"] - table[f"{c}_lo"]) / (2 * Z95)) ** 2) for c in channels))


def case_with_plain_fit(robot: str, degradation: str, folder: Path):
    """``(case, validation, predicted_plain, kept)``: the robot's records degraded (``none``: as they are), how
    the validation is given, and the plain least-squares fit's prediction of the test record with the rows it kept."""
    if degradation == "none":
        folder.mkdir(parents=True, exist_ok=True)
        case, validation = ROBOTS[robot](folder), "given"
    else:
        case, validation = degraded_case(robot, degradation, folder)
    plain = PlainFit(case.robot)
    cutoff, theta = plain.fit(case.records["train"], case.records["validate"])
    predicted_plain, kept = plain.predict(case.records["test"], cutoff, theta)
    return case, validation, predicted_plain, kept


def candidates_on_records(robot: str, degradation: str, folder: Path) -> list[str]:
    """The table's lines: per candidate, its test ratios to the plain fit and its band variance per record."""
    case, validation, predicted_plain, kept = case_with_plain_fit(robot, degradation, folder)
    test = case.records["test"]
    run = run_verb(case, validation, "identify", folder)
    if run["exit"] != 0:
        return [f"identify exits {run['exit']}: {run['message']}"]
    document = json.loads((folder / "identify.json").read_text())
    selection = document.get("model_selection") or {}
    lines = [f"{robot}, {degradation}: identify chose {selection.get('chosen')} ({selection.get('reason')})", "",
             "| candidate | validation score | test / plain: total · mean · worst | per joint | band variance: "
             "train · validate · test | validate − train | test − train |", "|---|---|---|---|---|---|---|"]
    for candidate in selection.get("candidates", []):
        if not candidate.get("available"):
            continue
        name, variance = candidate["name"], {}
        for role in ("train", "validate", "test"):
            out = folder / f"{name}_{role}.csv"
            code, _, message = run_logged(["predict", "--model", str(folder / "identify.json"), "--alternative", name,
                                           "--data", str(case.files[role]), "--out", str(out)])
            if code != 0:
                raise RuntimeError(f"oed predict --alternative {name} on {role}: {message}")
            table = pd.read_csv(out)
            channels = [c for c in table.columns if c.startswith("tau") and c[3:].isdigit()]
            variance[role] = band_variance(table, channels)
            if role == "test":
                rows, values = at_recorded(test.t, table["t"].to_numpy(), table[channels].to_numpy())
                use = kept[rows] & ~resent(test)[rows]
                rows, values = rows[use], values[use]
                mse = np.mean((test.tau[rows] - values) ** 2, axis=0)
                reference = np.mean((test.tau[rows] - predicted_plain[rows]) ** 2, axis=0)
                ratio = mse / reference
        lines.append(f"| {name} | {candidate.get('score'):.3f} | {mse.sum() / reference.sum():.3f} · {ratio.mean():.3f} · "
                     f"{ratio.max():.3f} (j{ratio.argmax() + 1}) | {', '.join(f'{r:.3f}' for r in ratio)} | "
                     f"{variance['train']:.4f} · {variance['validate']:.4f} · {variance['test']:.4f} | "
                     f"{variance['validate'] - variance['train']:+.4f} | {variance['test'] - variance['train']:+.4f} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda", choices=sorted(ROBOTS))
    parser.add_argument("--degradation", default="short", choices=[*DEGRADATIONS, "none"])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        print("\n".join(candidates_on_records(args.robot, args.degradation, Path(folder))), flush=True)


if __name__ == "__main__":
    main()
