"""Which parameter directions carry a joint's test error when the test leaves the training range (h-extrap).

The case of ``tests/test_unseen_robot_cells.py``: the PUMA's 6 joints, training and validation over the lowest 35 % of
the shoulder's range, the test over all of it. For the truth as the labs draw it (``--truth urdf``, the description's
bodies ±20 % in the URDF's link frames) or as they drew it until h-extrap (``--truth dh``: the DH table's parameters
±20 % read in the URDF's frames), ``oed identify`` on its defaults and with ``--consistent --prior-weight W`` for each
weight of the grid, then, per estimate, the test MSE over the noise floor of joints 1 and 2 (``oed predict`` on the
test record, at the recorded samples) and its error along the directions the test amplifies most: the generalised
eigenvectors of ``A_j v = λ G v`` (``G`` the training record's channel-weighted Gram matrix of the base regressor on
the noise-free states, ``A_j`` the test record's mean Gram matrix of joint ``j``), so that an error of ``c`` training
standard deviations along ``v`` costs ``λ c²`` of test MSE.

Run: ``.venv/bin/python -m tests.extrapolation_directions [--truth urdf|dh]`` (a script beside the tests, which it
imports; not collected by pytest; about a minute on a quiet machine).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
from scipy.linalg import eigh

from benchmarks.bench_real_robots import PlainFit, at_recorded, run_quiet
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.physical_parameters import consistency_margin
from oed.fourier import random_fourier
from tests.test_unseen_robot_cells import CELLS
from tests.test_unseen_robot_labs import confined, write_records
from tests.test_unseen_robots import FRICTION, NOISE, times, truth
import tests.test_unseen_robot_labs as labs

WEIGHTS = ("0", "0.1", "1", "10", "100")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--truth", choices=("urdf", "dh"), default="urdf")
    args = parser.parse_args()
    case = next(cell for cell in CELLS if "lowest 35" in cell.name).lab
    if args.truth == "dh":  # the draw before h-extrap
        labs.true_theta = lambda lab, folder: truth(build_model(lab.robot(), "internal", FRICTION))
    folder = Path(tempfile.mkdtemp(prefix="extrapolation-"))
    urdf, records, files, spread = write_records(case, folder)
    floor = (NOISE * spread) ** 2
    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, plain_theta = plain.fit(records["train"], records["validate"], rate_hz=case.train.rate_hz)
    predicted_plain, kept = plain.predict(records["test"], cutoff, plain_theta)
    test = records["test"]
    print(f"plain OLS: test MSE / floor {np.round(np.mean((test.tau - predicted_plain)[kept] ** 2, 0) / floor, 1)}")

    robot = load_robot(urdf=urdf)
    model = build_model(robot, "internal", FRICTION)
    theta = labs.true_theta(case, folder)
    n, K = robot.n_joints, model.base.K
    print("truth's link pseudo-inertia margins (URDF frames):",
          [round(consistency_margin(theta[10 * k: 10 * k + 10]), 4) for k in range(n)])
    limits = SimpleNamespace(n_joints=n, lower=np.asarray(robot.lower, float), upper=np.asarray(robot.upper, float),
                             velocity_limit=np.asarray(robot.velocity_limit, float))
    regressors = {}
    for role, log, seed in (("train", case.train, 11), ("test", case.test, 13)):
        t = times(log, np.random.default_rng(1000 + seed))
        within = confined(limits, *case.trained_range) if role != "test" else limits
        regressors[role] = model.evaluate_base(*random_fourier(within, seed=seed, frequency_hz=log.motion_hz).evaluate(t))
    true_base = K @ theta
    G = sum(regressors["train"][:, c, :].T @ regressors["train"][:, c, :] / floor[c] for c in range(n))

    estimates, measured = {}, {}

    def run(label: str, options: list[str], alternatives: tuple[str | None, ...] = (None,)) -> None:
        result = folder / f"{label}.json"
        code, message = run_quiet(["identify", "--urdf", str(urdf), "--data", str(files["train"]), "--validate",
                                   str(files["validate"]), "--friction", FRICTION, *options, "--out", str(result)])
        if code:
            raise SystemExit(message)
        written = json.loads(result.read_text())["model_file"]
        for alternative in alternatives:
            name = label if alternative is None else alternative
            out = folder / f"{name}.csv"
            code, message = run_quiet(["predict", "--model", str(result), "--data", str(files["test"]), "--out", str(out),
                                       *(["--alternative", alternative] if alternative else [])])
            if code:
                raise SystemExit(message)
            table = pd.read_csv(out)
            rows, values = at_recorded(test.t, table["t"].to_numpy(), table[[f"tau{j + 1}" for j in range(n)]].to_numpy())
            rows, values = rows[kept[rows]], values[kept[rows]]
            measured[name] = np.mean((test.tau[rows] - values) ** 2, 0) / floor
            if alternative in ("ols", "wls"):
                estimates[name] = np.asarray(written["alternatives"][alternative]["theta"])
            elif "--consistent" in options:
                links = np.concatenate([np.ravel(link) for link in written["consistent"]["links"]])
                effects = [written["consistent"]["effects"][p] for p in model.parameter_names[10 * n:]]
                estimates[name] = K @ np.r_[links, effects]

    run("default", [], (None, "ols", "wls"))
    for weight in WEIGHTS:
        run(f"consistent, prior weight {weight}", ["--consistent", "--prior-weight", weight])
    estimates["the description (prior)"] = K @ np.r_[robot.standard_parameters, theta[10 * n:]]
    print("\ntest MSE / floor per joint (oed predict, recorded samples):")
    for name, values in measured.items():
        print(f"  {name:32s} {np.round(values, 1).tolist()}")
    for j in (0, 1):
        A = regressors["test"][:, j, :].T @ regressors["test"][:, j, :] / regressors["test"].shape[0]
        lam, V = eigh(A, G)
        order = np.argsort(lam)[::-1]
        lam, V = lam[order], V[:, order]
        print(f"\njoint {j + 1}: test MSE per unit of training chi2 along the top directions (floors): "
              f"{np.round(lam[:4] / floor[j], 2).tolist()}")
        v = V[:, 0] / np.linalg.norm(V[:, 0])
        rigid = np.array([not name.startswith(("fv", "fc", "off")) for name in model.base.names])
        body = np.where(rigid, v, 0.0) / np.linalg.norm(v[rigid])
        print(f"  direction 1: its friction and offsets {', '.join(f'{model.base.names[i]} {v[i]:+.2f}' for i in np.flatnonzero(~rigid) if abs(v[i]) > 0.05)}"
              f" (of unit norm); its bodies' part, normalised: "
              + ", ".join(f"{model.base.names[i]} {body[i]:+.2f}" for i in np.argsort(-np.abs(body))[:6]))
        for name, estimate in estimates.items():
            error = estimate - true_base
            along = V.T @ G @ error
            print(f"  {name:32s} error along directions 1-3 (training sigmas) {np.round(along[:3], 1).tolist()}; "
                  f"model error on the test, MSE / floor {error @ A @ error / floor[j]:.1f}")


if __name__ == "__main__":
    main()
