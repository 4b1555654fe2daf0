"""Benchmark: the residual tracing of joint pairs (``estimation.diagnosis.candidates.coupling.traced_pairs``), run
once by every ``oed diagnose``, against the explicit projection it replaced and against one least-squares fit.

Records (KUKA LWR4+ URDF and runs of ``../shared/data/kuka_lwr4``; declared model internal, viscous; the 36
pairs ``viscous``, ``coulomb``, ``inertia`` on ``qj ± qj+1``):

1. the real run 1, 5 027 samples, derivatives of the file;
2. a simulated 14 000-sample log (``benchmarks/bench_diagnose.py`` part 3: ``oed simulate`` under PD control,
   two 7 s periods of a random 5-harmonic excitation, Coulomb friction and offsets the model lacks), its
   derivatives from a Fourier fit (80 harmonics of 1/7 Hz) without averaging the periods, and with (7 000).

For each: CPU time (``time.process_time``, the fastest of three, one BLAS thread as the CLI runs) of
``traced_pairs`` and of the explicit projection it replaced (:func:`explicit_projection`: a QR factorisation of
the weighted regressor, each pair's columns projected off it), their largest relative difference of the F
statistics (with the per-joint columns the declared model absorbs dropped from the projection, as in
``tests/test_traced_pairs.py``, and as the former code had them: fitted on their rounding noise) and whether they
keep the same pairs; the ratio to one ``numpy.linalg.lstsq`` of the declared model's stacked regressor (target:
``traced_pairs`` under one such fit). Run: ``python benchmarks/bench_traced_pairs.py``.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from bench_diagnose import DATA, seven_joint_log
from dynamics.effects.motor import KINDS, pair_combinations
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.runtime.threads import single_threaded_blas
from estimation.data.records import read_record
from estimation.datasets.kuka import load_kuka_run
from estimation.diagnosis.candidates.coupling import pair_tests, per_joint_extra, traced_pairs
from estimation.estimators.effect_blocks import States, effect_columns
from estimation.estimators.identification_problem import stack
from estimation.preprocessing.plan import choose_preprocessing, prepare


def cpu_seconds(function, repeats: int = 3) -> float:
    """The fastest of ``repeats`` calls, CPU s (all threads of this process)."""
    times = []
    for _ in range(repeats):
        start = time.process_time()
        function()
        times.append(time.process_time() - start)
    return min(times)


def explicit_projection(model, train, pairs, *, drop_absorbed: bool = True) -> list[float | None]:
    """Each pair's F statistic (``None``: absorbed) as ``traced_pairs`` computed it before: the ordinary fit by SVD,
    the weighted regressor factored by QR, each pair's columns projected off it, then off the per-joint columns by
    least squares; with ``drop_absorbed``, per-joint columns whose projection is rounding noise (below 1e-20 of
    their squared norm) left out instead of fitted."""
    problem = stack(model, train)
    Y, y, m = problem.Y.reshape(-1, problem.Y.shape[2]), problem.y.reshape(-1), model.n_channels
    theta, *_ = np.linalg.lstsq(Y, y, rcond=None)
    residual = (y - Y @ theta).reshape(-1, m)
    weight = np.tile(1.0 / np.sqrt(np.maximum(np.mean(residual**2, axis=0), 1e-300)), train.n_samples)
    Q, _ = np.linalg.qr(Y * weight[:, None])
    r0 = y * weight - Q @ (Q.T @ (y * weight))
    states = States(train.q, train.dq, train.ddq)
    statistics = []
    for pair in pairs:
        extra = per_joint_extra(model, pair)
        C = np.concatenate([effect_columns(model.kind, model.robot, effect, m, states).reshape(y.size, -1)
                            for effect in [*extra, pair]], axis=1) * weight[:, None]
        own = np.sum(C**2, axis=0)
        C = C - Q @ (Q.T @ C)
        base = C[:, :-1][:, np.sum(C[:, :-1] ** 2, axis=0) > 1e-20 * own[:-1]] if drop_absorbed else C[:, :-1]
        column, r1 = C[:, -1], r0
        if base.shape[1]:
            r1 = r0 - base @ np.linalg.lstsq(base, r0, rcond=None)[0]
            column = column - base @ np.linalg.lstsq(base, column, rcond=None)[0]
        norm = float(column @ column)
        if norm <= 1e-12 * max(float(r1 @ r1), 1e-300):
            statistics.append(None)
            continue
        gain = float(column @ r1) ** 2 / norm
        statistics.append(gain / ((float(r1 @ r1) - gain) / (y.size - Y.shape[1] - len(extra) - 1)))
    return statistics


def largest_difference(tests, reference) -> tuple[float, str]:
    """The largest relative difference of the F statistics and its pair."""
    return max((abs(test.statistic - value) / abs(value), test.pair.name) for test, value in zip(tests, reference)
               if value is not None and test.statistic is not None)


def compare(label: str, model, train) -> None:
    pairs = [pair for kind in KINDS for pair in pair_combinations(model.robot.n_joints, kind)]
    Y, y = stack(model, train).stacked()
    with single_threaded_blas():
        fit = cpu_seconds(lambda: np.linalg.lstsq(Y, y, rcond=None))
        gram = cpu_seconds(lambda: traced_pairs(model, train, pairs))
        explicit = cpu_seconds(lambda: explicit_projection(model, train, pairs, drop_absorbed=False), repeats=1)
        tests, reference = pair_tests(model, train, pairs), explicit_projection(model, train, pairs)
        former = explicit_projection(model, train, pairs, drop_absorbed=False)
    same_absorbed = all((test.statistic is None) == (value is None) for test, value in zip(tests, reference))
    difference, worst = largest_difference(tests, reference)
    threshold = 1e-3 / len(pairs)
    kept = [test.pair for test, value in zip(tests, reference) if value is not None and test.p_value < threshold]
    print(f"{label}, {train.n_samples} samples: traced_pairs {gram * 1e3:.0f} ms CPU ({gram / fit:.2f} least-squares "
          f"fits of {Y.shape[0]} x {Y.shape[1]}, {fit * 1e3:.0f} ms; target < 1), explicit projection "
          f"{explicit * 1e3:.0f} ms ({explicit / gram:.1f}x); F statistics within {difference:.1e} ({worst}), absorbed "
          f"pairs {'the same' if same_absorbed else 'DIFFERENT'}, kept pairs "
          f"{'the same' if kept == traced_pairs(model, train, pairs) else 'DIFFERENT'} ({len(kept)} of {len(pairs)}); "
          "the former code's within {:.1e} ({})".format(*largest_difference(tests, former)))


def main() -> None:
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent")
        return
    model = build_model(load_robot(urdf=DATA / "kuka_lwr4.urdf"), "internal", "viscous")
    compare("KUKA LWR4+ run 1", model, load_kuka_run(DATA / "kuka_lwr4_HW_measurements_1.npz"))
    with tempfile.TemporaryDirectory() as folder:
        (path,) = seven_joint_log(Path(folder), records=("train",))
        train = read_record(path, model=model)[0]
        for average in ("no", "yes"):
            plan = choose_preprocessing(train, frequency_hz=1 / 7, harmonics=80, average_periods=average)
            compare(f"simulated 7-joint log, periods averaged: {average}", model, prepare(train, plan))


if __name__ == "__main__":
    main()
