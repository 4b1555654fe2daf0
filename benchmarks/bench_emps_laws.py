"""EMPS's friction laws on a record no choice saw: each law declared to ``oed identify`` on
:func:`benchmarks.bench_real_robots.emps`'s split (DATA_EMPS's first two thirds to train, its last third to
validate), then ``oed predict`` on DATA_EMPS_PULSES; the test MSE against the recorded force (N²).

The evidence behind ``tests.corpus.cases.EMPS_LOOP`` (benchmarks/README.md, "The two strict xfails").

Run: ``PYTHONPATH=. python benchmarks/bench_emps_laws.py [LAWS ...]`` (each a ``--friction`` list).
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

from benchmarks.bench_real_robots import emps, run_quiet

LAWS = ("viscous", "viscous,coulomb,offset", "viscous,sigmoid", "viscous,sigmoid,offset", "viscous,coulomb:tanh,offset",
        "viscous,coulomb,offset,delay", "viscous,sigmoid,delay")


def main(laws: list[str]) -> None:
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        case = emps(folder)
        print("| declared (`--friction`) | chosen | validation MSE | test MSE |\n|---|---|---|---|")
        for friction in laws:
            result, metrics = folder / "result.json", folder / "metrics.json"
            code, _ = run_quiet(["identify", *case.robot, "--data", str(case.files["train"]), "--validate",
                              str(case.files["validate"]), "--friction", friction, "--out", str(result)])
            if code:
                print(f"| {friction} | exit {code} | | |")
                continue
            document = json.loads(result.read_text())
            code, _ = run_quiet(["predict", "--model", str(result), "--data", str(case.files["test"]), "--metrics",
                              str(metrics), "--out", str(folder / "predicted.csv")])
            test = json.loads(metrics.read_text())["mse"]["tau1"] if code == 0 else float("nan")
            print(f"| {friction} | {document['chosen']} | {document['validation']['mse']['tau1']:.3f} | {test:.3f} |",
                  flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or list(LAWS))
