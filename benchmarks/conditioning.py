"""Conditioning of the internal, external and combined models (PUMA paper, Tables I–II).

Designs an optimal trajectory for each model, evaluates every trajectory under all three models
(−log det(Y_bᵀY_b), condition number, relative standard deviation of every base parameter for
equal unit noise, ``σ_i = sqrt((Y_bᵀY_b)⁻¹_ii) / |θ_b,i|`` at the PUMA's nominal parameters), and
writes CSV and Markdown tables plus the figure of each trajectory.

The "as-executed" columns (Table II: the trajectory after tracking by the robot) come from the
simulator: each design is tracked by the PUMA under joint PD control (viscous friction, default
gains) and the criteria are evaluated at the executed ``(q, dq, ddq)``.

    python benchmarks/conditioning.py --out benchmarks/results [--starts 4]
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from dynamics.models import ModelKind, build_model
from dynamics.robots import load_robot
from dynamics.simulation.simulator import NoiseModel, Simulator
from dynamics.runtime.output_files import save_figure
from oed.bounds import PUMA_BOUNDS
from oed.excitation import design_excitation
from oed.design_plot import plot_trajectory


def evaluate_states(robot, kind: str, q, dq, ddq) -> dict[str, float]:
    """−log det, condition number and relative parameter standard deviations of one model at given states."""
    model = build_model(robot, kind)
    Y = model.evaluate_base(q, dq, ddq).reshape(-1, model.n_base)
    M = Y.T @ Y
    values = {"viscous": 1.0} if any(effect.name == "viscous" for effect in model.effects) else {}
    theta = model.base.to_base(model.nominal_parameters(**values))
    sigma = np.sqrt(np.diag(np.linalg.inv(M)))
    # parameters whose nominal value is (numerically) zero have no relative deviation
    relative = np.where(np.abs(theta) > 1e-6, sigma / np.where(np.abs(theta) > 1e-6, np.abs(theta), 1.0), np.nan)
    return {"logdet_cost": float(-np.linalg.slogdet(M)[1]), "cond": float(np.linalg.cond(Y)),
            "rel_std_median": float(np.nanmedian(relative)), "rel_std_max": float(np.nanmax(relative))}


def conditioning_rows(robot, trajectories: Mapping[str, object],
                      executed: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None) -> pd.DataFrame:
    """One row per (designed-for model, evaluated-under model); ``executed[designed_for] = (q, dq, ddq)``."""
    rows = []
    for designed_for, trajectory in trajectories.items():
        _, q, dq, ddq = trajectory.sample(1000.0)
        for kind in ModelKind:
            row = {"designed_for": designed_for, "evaluated_under": kind.value}
            row.update({f"optimised_{k}": v for k, v in evaluate_states(robot, kind.value, q, dq, ddq).items()})
            if executed and designed_for in executed:
                row.update({f"executed_{k}": v for k, v in evaluate_states(robot, kind.value, *executed[designed_for]).items()})
            rows.append(row)
    return pd.DataFrame(rows)


def markdown(table: pd.DataFrame) -> str:
    """A GitHub Markdown table (no extra dependency)."""
    cells = [[f"{v:.4g}" if isinstance(v, float) else str(v) for v in row] for row in table.itertuples(index=False)]
    lines = ["| " + " | ".join(table.columns) + " |", "|" + "---|" * len(table.columns)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in cells]) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results"))
    parser.add_argument("--starts", type=int, default=4)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    robot = load_robot("puma560", joints=3)
    trajectories = {}
    args.out.mkdir(parents=True, exist_ok=True)
    for kind in ModelKind:
        result = design_excitation(robot, model=kind.value, bounds=PUMA_BOUNDS, starts=args.starts, seed=args.seed)
        trajectories[kind.value] = result.trajectory
        print(f"{kind.value}: cost {result.cost:.3f}, cond {result.cond:.2f} ({result.total_time_s:.1f} s)")
    simulator = Simulator(robot, "viscous", noise=NoiseModel.none())
    executed = {}
    for kind, trajectory in trajectories.items():
        run = simulator.run(trajectory, periods=1, warmup_periods=1, with_derivatives=True)
        executed[kind] = (run.q, run.dq, run.ddq)
        save_figure(plot_trajectory(trajectory, PUMA_BOUNDS, executed=(run.t - run.t[0], run.q, run.dq, run.ddq),
                                    title=f"optimised for the {kind} model: designed and executed"),
                    args.out / f"trajectory_{kind}.png")
    table = conditioning_rows(robot, trajectories, executed)
    table.to_csv(args.out / "conditioning.csv", index=False)
    (args.out / "conditioning.md").write_text(markdown(table))
    print(table.to_string(index=False))


if __name__ == "__main__":
    main()
