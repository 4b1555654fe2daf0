"""Benchmark (issue 34): a sweep configuration's default answers scored on other records than its test record.

A row of :mod:`bench_sweep` compares the default `oed identify` / `oed diagnose` with the plain least-squares fit on
one test record. When that record repeats the training or the validation motion (the KUKA LWR4+'s runs 1 and 2 are
the same motion; run 3 is another, twice as fast), the same models scored on the other records say whether a ratio
above 1 is the model's or the record's. Here each verb runs once on the configuration's training (and validation)
record, with its defaults, as :mod:`bench_sweep` runs it; then ``oed predict`` on each record asked for (``--on``,
the sweep's roles ``train``/``validate``/``test`` or a log's own records such as ``run1``), and the plain fit of
:mod:`bench_sweep` (its cut-off chosen on the configuration's validation record) on the same recorded samples.

Printed per verb and record: the total and the mean of the joints' ratios of test MSE to the plain fit's, and per
joint the ratio with the standard error of the difference (model − plain fit) over the plain fit's MSE, taken over
``--blocks`` contiguous blocks of the record (a mean of batch means); then the model's and the plain fit's MSE per
joint (N²m²).

Run: ``PYTHONPATH=. python benchmarks/bench_sweep_records.py kuka-312 --on run1,run2`` (about 2 minutes on the
KUKA), ``... kuka-231 --on run1,run3 --verbs identify``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import benchmarks.bench_real_robots as real  # noqa: E402
import benchmarks.bench_sweep as sweep  # noqa: E402


def oed(*arguments: str) -> None:
    """``python -m oed ARGUMENTS``; a failure stops the benchmark with the command's message."""
    process = subprocess.run([sys.executable, "-m", "oed", *arguments], capture_output=True, text=True)
    if process.returncode != 0:
        sys.exit(f"oed {arguments[0]} exited {process.returncode}: {process.stderr.strip()[-400:]}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", help="a configuration of bench_sweep.py (its --list names them)")
    parser.add_argument("--on", required=True, help="records to score, comma-separated: train, validate, test or a "
                                                    "record of the log (run1, run2, run3 on the KUKA)")
    parser.add_argument("--verbs", default="identify,diagnose", help="verbs, comma-separated (default: %(default)s)")
    parser.add_argument("--blocks", type=int, default=10, help="contiguous blocks for the standard errors")
    args = parser.parse_args()
    config = next((item for item in sweep.CONFIGS if item.name == args.config), None)
    if config is None:
        sys.exit(f"no configuration {args.config!r} (bench_sweep.py --list)")
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        log = {"kuka": sweep.kuka_log, "panda": sweep.panda_log, "emps": sweep.emps_log,
               "tx40": lambda: sweep.tx40_log(folder)}[config.robot]()
        records, files = sweep.config_records(config, log, folder)
        for key in args.on.split(","):
            if key not in records:
                records[key] = log.records[key]
                files[key] = sweep.write(log, records[key], config.layout, folder / f"{key}.csv")
        plain = sweep.SweepPlainFit(log.robot)
        roles = [records[role] for role in config.roles]
        cutoff, theta = plain.fit_on(records["train"], records.get("validate", records["train"]), roles)
        validate = ["--validate", str(files["validate"])] if "validate" in files else []
        for verb in args.verbs.split(","):
            result = folder / f"{verb}.json"
            friction = ["--friction", sweep.FRICTION] if verb == "identify" else []
            oed(verb, *log.robot, *log.options, "--data", str(files["train"]), *validate, *friction, "--out",
                str(result), "--quiet")
            for key in args.on.split(","):
                predictions = folder / f"{verb}_{key}.csv"
                oed("predict", "--model", str(result), "--data", str(files[key]), "--out", str(predictions))
                table = pd.read_csv(predictions)
                channels = [c for c in table.columns if c.startswith("tau") and c[3:].isdigit()]
                record = records[key]
                index, values = real.at_recorded(record.t, table["t"].to_numpy(), table[channels].to_numpy())
                predicted, kept = plain.predict(record, cutoff, theta)
                common = np.intersect1d(np.flatnonzero(kept), index)
                model = (record.tau[common] - values[np.isin(index, common)]) ** 2
                reference = (record.tau[common] - predicted[common]) ** 2
                ratio = model.mean(axis=0) / reference.mean(axis=0)
                blocks = np.array_split(np.arange(common.shape[0]), args.blocks)
                differences = np.array([(model[block].mean(axis=0) - reference[block].mean(axis=0))
                                        / reference.mean(axis=0) for block in blocks])
                error = differences.std(axis=0, ddof=1) / np.sqrt(len(blocks))
                print(f"{config.name} {verb} on {key} ({common.shape[0]} samples): total "
                      f"{model.sum() / reference.sum():.3f} · mean {ratio.mean():.3f}; per joint "
                      + ", ".join(f"{r:.2f} ± {e:.2f}" for r, e in zip(ratio, error)), flush=True)
                print(f"  MSE model {np.array2string(model.mean(axis=0), precision=4)}, plain fit "
                      f"{np.array2string(reference.mean(axis=0), precision=4)}", flush=True)


if __name__ == "__main__":
    main()
