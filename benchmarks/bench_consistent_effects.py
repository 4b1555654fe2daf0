"""The physically consistent fit with the diagnosed effects, on a real robot: validation and test MSE per joint.

KUKA LWR4+ (``../shared/data/kuka_lwr4``, FloBaRoID's runs): trained on run 1, validated on run 2 (where the
diagnosis confirms its effects and the prior's weight is chosen), tested on run 3 (no choice saw it). The
diagnosis starts from the declared model of ``oed diagnose`` (viscous friction) with its default candidates and
the joint pairs the residual traces; then, per joint (N²m²):

* consistent, declared effects (``estimation.consistent.identification.consistent_fit`` on the declared model);
* consistent, viscous + Coulomb + offset (the plain model of issue #34);
* consistent, diagnosed effects (``consistent_refit(diagnosis, …)``: shaped laws at their fitted shapes, delay);
* unconstrained, diagnosed effects (the diagnosis's ``after``);
* unconstrained, viscous + Coulomb + offset (weighted least squares).

Franka Panda (``../shared/data/panda``, one real log of Gaz et al.; ``--robot panda``): split by time into train
(t < 13.84 s: the ramp and the first period), validation (13.84–17.2 s) and test (from 17.2 s), written as CSV
files (q and torques as logged) and run through the command line as a user would: ``oed diagnose --consistent
--test`` (the derivatives, the logger's defects and the prior's weight chosen by the toolkit), ``oed identify
--consistent`` of the declared and of the plain models, then ``oed predict [--consistent]`` on the test file.

Run: ``PYTHONPATH=. python benchmarks/bench_consistent_effects.py [--robot kuka|panda]`` (2–3 min each).
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.consistent.identification import consistent_fit, consistent_refit
from estimation.diagnosis.candidates.coupling import coupling_candidates
from estimation.diagnosis.search import default_candidates, diagnose
from estimation.identification.fit import ImplausibleEstimateWarning, identify
from estimation.identification.validation import Comparison

SHARED = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"


def kuka_records():
    from estimation.datasets.kuka import load_kuka_run

    folder = SHARED / "kuka_lwr4"
    if not (folder / "kuka_lwr4.urdf").is_file():
        raise SystemExit(f"no KUKA LWR4+ data at {folder}")
    robot = load_robot(urdf=folder / "kuka_lwr4.urdf")
    runs = [load_kuka_run(folder / f"kuka_lwr4_HW_measurements_{index}.npz") for index in (1, 2, 3)]
    return robot, runs


def _row(label: str, validation: dict[str, float], test: dict[str, float]) -> str:
    cells = [f"{validation[c]:.3f} / {test[c]:.3f}" for c in validation]
    return (f"| {label} | " + " | ".join(cells)
            + f" | {sum(validation.values()):.2f} / {sum(test.values()):.2f} |")


def panda_table(folder: Path, declared: str) -> None:
    """The Panda through the command line (module docstring): files in ``folder``, the table printed."""
    import json

    import pandas as pd

    from oed.cli import main as oed

    log = SHARED / "panda" / "Trajectory_1" / "rbt_log"
    if not log.is_dir():
        raise SystemExit(f"no Panda data at {log}")
    urdf = str(SHARED / "panda" / "panda_gaz.urdf")
    t = np.loadtxt(log / "exciting_traj_time.txt")
    q = np.loadtxt(log / "exciting_traj_positions.txt").reshape(-1, 7)
    tau = np.loadtxt(log / "exciting_traj_torques.txt").reshape(-1, 7)
    frame = pd.DataFrame({"t": t, **{f"q{j + 1}": q[:, j] for j in range(7)},
                          **{f"tau{j + 1}": tau[:, j] for j in range(7)}})
    folder.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, low, high in (("train", 0.0, 13.84), ("validate", 13.84, 17.2), ("test", 17.2, np.inf)):
        files[name] = str(folder / f"{name}.csv")
        frame[(frame.t >= low) & (frame.t < high)].to_csv(files[name], index=False)
    common = ["--urdf", urdf, "--data", files["train"], "--validate", files["validate"], "--quiet"]

    def predicted(result: Path, consistent: bool) -> dict[str, float]:
        metrics = result.with_suffix(".metrics.json")
        assert oed(["predict", "--model", str(result), "--data", files["test"], "--out",
                    str(result.with_suffix(".csv")), "--metrics", str(metrics),
                    "--alternative", "consistent" if consistent else "unconstrained"]) == 0
        return json.loads(metrics.read_text())["mse"]

    report = folder / "report.json"
    assert oed(["diagnose", *common, "--test", files["test"], "--friction", declared, "--out", str(report),
                "--consistent"]) == 0
    rows = []
    for friction in (declared, "viscous,coulomb,offset"):
        result = folder / f"identify_{friction.replace(',', '_')}.json"
        assert oed(["identify", *common, "--friction", friction, "--consistent", "--out", str(result)]) == 0
        document = json.loads(result.read_text())
        rows.append(_row(f"consistent, {friction}, W = {document['consistent']['prior_weight']:g}",
                         document["consistent"]["validation"]["mse"], predicted(result, True)))
        selection = document["model_selection"]  # the top level is the chosen (consistent) model's
        unconstrained = next(c for c in selection["candidates"] if c["name"] == selection["base"])
        rows.append(_row(f"unconstrained, {friction}", unconstrained["validation_mse"], predicted(result, False)))
    document = json.loads(report.read_text())
    print("diagnosed effects:", [effect["name"] for effect in document["effects"]])
    rows.append(_row(f"consistent, diagnosed effects, W = {document['consistent']['prior_weight']:g}",
                     document["consistent"]["validation"]["mse"], predicted(report, True)))
    rows.append(_row("unconstrained, diagnosed effects", document["validation"]["after"]["mse"],
                     predicted(report, False)))
    channels = [f"tau{j}" for j in range(1, 8)]
    print("| model (validation / test, N²m²) | " + " | ".join(channels) + " | sum |")
    print("|---|" + "---|" * (len(channels) + 1))
    for row in rows:
        print(row)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=["kuka", "panda"], default="kuka")
    parser.add_argument("--declared", default="viscous", help="the diagnosis's declared effects (default: viscous)")
    parser.add_argument("--folder", type=Path, default=Path("out/bench_consistent_effects_panda"),
                        help="where the Panda's split files and results are written")
    args = parser.parse_args()
    if args.robot == "panda":
        panda_table(args.folder, args.declared)
        return
    robot, (train, validate, test) = kuka_records()
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImplausibleEstimateWarning)
        declared = build_model(robot, "internal", args.declared)
        started = time.perf_counter()
        candidates = default_candidates(declared) + coupling_candidates(declared, None, train=train)
        diagnosis = diagnose(declared, train, validate, candidates=candidates)
        diagnosed_s = time.perf_counter() - started
        after = diagnosis.after
        print("diagnosed effects:", [f"{effect.spec or effect.name} ({'+'.join(effect.channels)})"
                                     for effect in diagnosis.effects],
              "delay:", None if after.delay is None else after.delay.value, f"({diagnosed_s:.0f} s)")
        plain = identify(build_model(robot, "internal", "viscous,coulomb,offset"), train, validate)
        fits = {
            f"consistent, declared ({args.declared})": consistent_fit(diagnosis.before, train, validate),
            "consistent, viscous + Coulomb + offset": consistent_fit(plain, train, validate),
        }
        started = time.perf_counter()
        fits["consistent, diagnosed effects"] = consistent_refit(diagnosis, train, validate)
        refit_s = time.perf_counter() - started
        for label, fit in fits.items():
            rows.append(_row(f"{label} (W = {fit.estimate.prior_weight:g})", fit.validation.mse, fit.compare(test).mse))
        for label, result in (("unconstrained, diagnosed effects", after),
                              ("unconstrained, viscous + Coulomb + offset", plain)):
            predicted = result.predict(test)
            test_mse = Comparison(test.t, test.channels(result.model.channels), predicted,
                                  result.model.channels).mse
            rows.append(_row(label, result.validation.mse, test_mse))
    channels = list(after.model.channels)
    print(f"consistent refit with the diagnosed effects: {refit_s:.1f} s (5 prior weights)")
    print("| model (validation run 2 / test run 3, N²m²) | " + " | ".join(channels) + " | sum |")
    print("|---|" + "---|" * (len(channels) + 1))
    for row in rows:
        print(row)


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()
