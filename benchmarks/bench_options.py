"""Benchmark (issue 34): ``oed identify`` with given options beside its defaults, per joint, on a real robot's split.

What a choice of the default answer would give on the test record, had it chosen otherwise: each option set (``""``
the defaults, ``"--method ols"``, ``"--cutoff 50 --consistent"``, …) is added to ``oed identify --friction
viscous,coulomb,offset`` on the training (and validation) record of :mod:`bench_real_robots`' split of a robot
(``--robot``) or of a configuration of :mod:`bench_sweep` (``--sweep``), then ``oed predict`` on the test record.
Every run is scored on the same recorded test samples (those every run predicted and the plain fit keeps, the
logger's re-sent rows left out), against the plain least-squares fit of the benchmark it comes from.

Printed per run: test MSE per joint, its ratio to the plain fit (total · mean of the joints' ratios · worst), the
model and derivatives chosen, and each candidate's validation MSE per joint (``model_selection``); then the runs
ranked on the test record by the criterion of the toolkit's choices
(:func:`estimation.identification.relative_error.relative_scores`: the mean over joints of each run's MSE over the
smallest any run reaches) beside their total, each joint's share of the plain fit's total test MSE, and the first
run's total minus each other's on contiguous blocks of the test record (``--blocks``: how sure the record is).

Run: ``PYTHONPATH=. python benchmarks/bench_options.py --robot tx40 "" "--method ols" "--cutoff 50"`` or
``PYTHONPATH=. python benchmarks/bench_options.py --sweep panda-noval "" "--cutoff 6 --method wls"``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import benchmarks.bench_real_robots as real  # noqa: E402
import benchmarks.bench_sweep as sweep  # noqa: E402
from estimation.identification.relative_error import relative_scores  # noqa: E402


def robot_case(name: str, folder: Path) -> tuple[list[str], dict[str, Path], dict[str, real.Record], float, np.ndarray]:
    """``(arguments, files, records, cut-off, plain prediction)`` of :mod:`bench_real_robots`' split of ``name``."""
    case = real.ROBOTS[name](folder)
    plain = real.PlainFit(case.robot)
    cutoff, theta = plain.fit(case.records["train"], case.records["validate"])
    predicted, kept = plain.predict(case.records["test"], cutoff, theta)
    return [*case.robot, *case.options], case.files, case.records, cutoff, np.where(kept[:, None], predicted, np.nan)


def sweep_case(name: str, folder: Path) -> tuple[list[str], dict[str, Path], dict[str, real.Record], float, np.ndarray]:
    """The same for the configuration ``name`` of :mod:`bench_sweep` (its files written as the sweep writes them)."""
    config = next(config for config in sweep.CONFIGS if config.name == name)
    log = {"kuka": sweep.kuka_log, "panda": sweep.panda_log, "emps": sweep.emps_log,
           "tx40": lambda: sweep.tx40_log(folder)}[config.robot]()
    records, files = sweep.config_records(config, log, folder)
    plain = sweep.SweepPlainFit(log.robot)
    cutoff, theta = plain.fit_on(records["train"], records.get("validate", records["train"]), list(records.values()))
    predicted, kept = plain.predict(records["test"], cutoff, theta)
    return [*log.robot, *log.options], files, records, cutoff, np.where(kept[:, None], predicted, np.nan)


def identify(arguments: list[str], files: dict[str, Path], options: list[str], folder: Path, label: str) -> dict | None:
    """``oed identify`` with ``options``, then ``oed predict`` on the test record: ``{t, predicted, result}``."""
    result, predictions = folder / f"{label}.json", folder / f"{label}.csv"
    validate = ["--validate", str(files["validate"])] if "validate" in files else []
    code, _ = real.run_quiet(["identify", *arguments, "--data", str(files["train"]), *validate, "--friction",
                           real.FRICTION, *options, "--out", str(result)])
    if code != 0:
        return None
    code, _ = real.run_quiet(["predict", "--model", str(result), "--data", str(files["test"]), "--out", str(predictions)])
    if code != 0:
        return None
    table = pd.read_csv(predictions)
    channels = [column for column in table.columns if column.startswith("tau") and column[3:].isdigit()]
    return {"t": table["t"].to_numpy(), "predicted": table[channels].to_numpy(),
            "result": json.loads(result.read_text())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--robot", choices=sorted(real.ROBOTS), help="bench_real_robots.py's split of this robot")
    where.add_argument("--sweep", help="a configuration of bench_sweep.py (--list there names them)")
    parser.add_argument("options", nargs="+", help='option sets, each one argument ("" for the defaults)')
    parser.add_argument("--blocks", type=int, default=10,
                        help="contiguous blocks of the test record for the uncertainty of the totals (default 10)")
    args = parser.parse_args()
    if not real.DATA.is_dir():
        sys.exit(f"no real data at {real.DATA}")
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        arguments, files, records, cutoff, plain = (robot_case(args.robot, folder) if args.robot
                                                    else sweep_case(args.sweep, folder))
        test = records["test"]
        runs = {text or "(defaults)": identify(arguments, files, shlex.split(text), folder, f"run{index}")
                for index, text in enumerate(args.options)}
    common = np.flatnonzero(np.all(np.isfinite(plain), axis=1) & ~real.resent(test))
    at = {}
    for label, run in runs.items():
        if run is None:
            print(f"{label}: exit != 0")
            continue
        at[label] = real.at_recorded(test.t, run["t"], run["predicted"])
        common = np.intersect1d(common, at[label][0])
    reference = np.mean((test.tau[common] - plain[common]) ** 2, axis=0)
    channels = [f"tau{j + 1}" for j in range(reference.shape[0])]
    print(f"plain fit: cut-off {cutoff:g} Hz, test MSE {np.round(reference, 4).tolist()} "
          f"(total {reference.sum():.4g}) on {common.shape[0]} of {test.t.shape[0]} test samples")
    print("each joint's share of the plain fit's total test MSE:", np.round(reference / reference.sum(), 3).tolist())
    errors, squared = {}, {"plain fit": (test.tau[common] - plain[common]) ** 2}
    for label, (index, values) in at.items():
        squared[label] = (test.tau[common] - values[np.isin(index, common)]) ** 2
        mse = np.mean(squared[label], axis=0)
        errors[label] = dict(zip(channels, mse, strict=True))
        ratio = mse / reference
        result = runs[label]["result"]
        selection, plan = result.get("model_selection") or {}, result.get("preprocessing") or {}
        print(f"\n{label}: total {mse.sum() / reference.sum():.3f} · mean {ratio.mean():.3f} · worst {ratio.max():.3f} "
              f"(j{ratio.argmax() + 1}); per joint {np.round(ratio, 3).tolist()}; test MSE {np.round(mse, 4).tolist()}")
        print(f"  chose {selection.get('chosen')} ({selection.get('selection')}), derivatives {plan.get('method')} "
              f"{plan.get('cutoff_hz')} Hz")
        for candidate in selection.get("candidates", []):
            validation = candidate.get("validation_mse")
            if validation:
                print(f"  validation {candidate['name']}"
                      + ("" if candidate.get("prior_weight") is None else f" (prior weight {candidate['prior_weight']:g})")
                      + f": {[round(value, 4) for value in validation.values()]} total {sum(validation.values()):.4g}"
                      + f" score {candidate.get('score'):.4f}")
    if len(errors) > 1:
        scores = relative_scores(errors, tuple(channels))
        print("\nthe runs on the test record by the choices' criterion (mean over joints of MSE / the smallest any run "
              "reaches), and the total / plain:")
        for label in sorted(scores, key=scores.__getitem__):
            print(f"  {scores[label]:.4f}  {sum(errors[label].values()) / reference.sum():.3f}  {label}")
    print_block_differences(squared, reference.sum(), args.blocks)


def print_block_differences(squared: dict[str, np.ndarray], total: float, blocks: int) -> None:
    """How sure the test record is of each total: the first run's total MSE minus each other's (and the plain
    fit's) on ``blocks`` contiguous blocks of the common samples, over the plain fit's total; mean ± the standard
    error of the blocks' mean, and on how many blocks the first run is worse."""
    labels = [label for label in squared if label != "plain fit"]
    if not labels or blocks < 2:
        return
    first = squared[labels[0]].sum(axis=1)
    parts = np.array_split(np.arange(first.shape[0]), blocks)
    print(f"\n{labels[0]} minus each other run, total MSE on {blocks} contiguous blocks over the plain fit's total:")
    for label in [*labels[1:], "plain fit"]:
        other = squared[label].sum(axis=1)
        difference = np.array([(first[part].mean() - other[part].mean()) / total for part in parts])
        print(f"  {label}: {difference.mean():+.4f} ± {difference.std(ddof=1) / np.sqrt(blocks):.4f} "
              f"(worse on {int(np.sum(difference > 0))} of {blocks})")


if __name__ == "__main__":
    main()
