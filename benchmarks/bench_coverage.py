"""Monte-Carlo coverage of the 95 % intervals in the demo's setting (issue 13).

Setting (as ``make demo``): PUMA 560, first three joints, viscous + Coulomb (``tanh(dq/0.05)``) +
offset on every joint, a stiff 20 Hz joint PD, torque noise 0.2 N·m, an optimal excitation
(``design_excitation(robot, model="internal", starts=2, seed=0)``) simulated over three periods
after one warm-up period, derivatives from a Fourier fit of the averaged periods with the hold
compensated. The demo fits 15 harmonics; the tracking response to the Coulomb law is much richer,
and 15 (or 40, 100) harmonics leave a deterministic error in ddq, dq that biases the estimates
(noise-free fit: residual RMS 2.0 / 0.39 / 0.51 N·m, fc3 and fv3 15 standard deviations off);
300 harmonics leave 0.10 / 0.04 / 0.01 N·m (below the averaged noise, 0.2/√3) and every bias
under 0.3 standard deviation; 1000 overfit the encoder quantisation. Default here: 300. The model knows the Coulomb law's smoothing (0.05 rad/s): every parameter
then enters linearly; an estimator that also estimates the smoothing plugs in as ``estimate``.

Noise realisations: the torque noise is measurement noise only (the controller sees the true
state and applies a noiseless torque; the simulator adds the noise to the recorded torque), so
the robot is simulated once without noise and each realisation adds fresh Gaussian noise to the
recorded torques; the encoder quantisation of ``q`` is deterministic and kept.

**Shaped fit** (``--model shaped``): the demo as it runs now (``oed.demo``): the simulated robot as
above under a 10 Hz joint PD, the train record (three periods, 15 000 samples, simulation seed 1),
derivatives from a 250-harmonic Fourier fit over all periods on their own time stamps
(``average=False``, the torques as recorded), and the model ``viscous,coulomb:tanh,offset`` fitted
by :func:`estimation.identification.fit.identify` (variable projection: the three smoothing velocities
``vc1..vc3`` estimated with the linear coefficients; ``--covariance hac``: the batch-means sandwich,
``classical``: the white-noise covariance, both from the full Jacobian). Checked: every base
parameter, Coulomb coefficient and smoothing velocity (true 0.05 rad/s).

``--encoder-phase`` draws the quantisation error anew in each realisation (:func:`noisy_encoder`).
Without it every realisation shares one quantised ``q``, hence one deterministic derivative error,
and joint 1's parameters, which the velocity reversals determine to 0.2 % (vc1 ± 1e-4 rad/s),
carry a bias no residual-based standard deviation can cover: the noise-free fit of that record has
vc1, fc1, fv1 at −1.5, −1.3, +1.3 standard deviations; with exact positions (no quantisation) −0.2,
−0.6, +0.6; with the true ``q, dq, ddq`` 0. That Monte Carlo conditions on one quantisation pattern;
repeated experiments differ by more than an encoder count (6e-6 rad on joint 1), so the drawn
phase is the coverage a user's intervals have. Both are reported (benchmarks/README.md).
Run: ``python -m benchmarks.bench_coverage [--realisations 200] [--model linear|shaped|both]
[--covariance hac|classical|both] [--encoder-phase]``.
"""

from __future__ import annotations

import argparse
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np

from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.sensors import NoiseModel, encoder_resolution
from dynamics.simulation.simulator import Simulator
from dynamics.runtime.threads import single_threaded_blas
from estimation.uncertainty.coverage import EstimateDraw, identification_draw, monte_carlo_coverage
from estimation.identification.fit import identify
from estimation.preprocessing.fourier_series import design_matrix
from estimation.estimators.least_squares import WeightedLeastSquares, stack
from estimation.preprocessing.differentiation import FourierDifferentiation, average_periods, fill_derivatives

TAU_STD = 0.2


def demo_setting(*, design: bool = True, periods: int = 3, harmonics: int = 300):
    """``(clean record, model, truth of its base parameters, differentiation)`` of the demo."""
    robot = load_robot("puma560", joints=3)
    simulator = Simulator(robot, "viscous,coulomb,offset", noise=replace(NoiseModel(), tau_std=0.0))
    if design:
        from oed.excitation import design_excitation

        trajectory = design_excitation(robot, model="internal", starts=2, seed=0).trajectory
    else:
        from oed.fourier import random_fourier

        trajectory = random_fourier(robot, seed=3, frequency_hz=0.1)
    clean = simulator.run(trajectory, simulator.default_controller(bandwidth_hz=20.0), periods=periods,
                          warmup_periods=1, seed=0).measurements
    model = build_model(robot, "internal", ("viscous", CoulombFriction(smoothing=0.05), "offset"))
    truth = dict(zip(model.base.names, model.base.to_base(simulator.true_theta(model))))
    differentiation = FourierDifferentiation(frequency_hz=trajectory.frequency_hz, harmonics=harmonics)
    return clean, model, truth, differentiation


def noisy(clean, std: float = TAU_STD):
    """``seed -> measurements`` with fresh torque noise."""
    def realise(seed: int):
        noise = np.random.default_rng(seed).normal(0.0, std, clean.tau.shape)
        return replace(clean, tau=clean.tau + noise)
    return realise


def linear_estimator(model, differentiation, covariance: str = "hac"):
    """``measurements -> EstimateDraw``: the demo's preprocessing, then weighted least squares.

    The derivatives come from ``q`` only, which every realisation shares (the same array): they
    are derived once and reused, and each realisation's torques are period-averaged as
    ``fill_derivatives`` would (the same numbers, 50 times faster at 300 harmonics).
    """
    cache: dict[int, object] = {}

    def estimate(measurements):
        key = id(measurements.q)
        entry = cache.get(key)
        if entry is None:  # (the threads share the cache: keep the entry, not the lookup)
            with single_threaded_blas():  # OpenBLAS threads spin against the other realisation's
                entry = (measurements.q, fill_derivatives(measurements, differentiation, held_torques=True))
            cache.clear()
            cache[key] = entry
        prepared = entry[1]
        tau = average_periods(measurements, differentiation.frequency_hz).tau
        data = replace(prepared, tau=tau)
        fit = WeightedLeastSquares(covariance=covariance).fit(stack(model, data)).estimate_
        return EstimateDraw(fit.names, fit.values, fit.std)
    return estimate


#: the demo's joint PD bandwidth and Fourier harmonics (``oed.demo``)
DEMO_BANDWIDTH_HZ = 10.0
DEMO_HARMONICS = 250
SHAPED_EFFECTS = "viscous,coulomb:tanh,offset"


def shaped_demo_setting(*, periods: int = 3, harmonics: int = DEMO_HARMONICS, encoder_phase: bool = False):
    """``(realise, shaped model, truth of its base and shape parameters, differentiation, samples)`` as
    ``oed.demo`` records its identification experiment; ``realise`` draws torque noise (and with
    ``encoder_phase`` the quantisation error too: :func:`noisy_encoder`)."""
    robot = load_robot("puma560", joints=3)
    simulator = Simulator(robot, "viscous,coulomb,offset", noise=replace(NoiseModel(), tau_std=0.0))
    from oed.excitation import design_excitation

    trajectory = design_excitation(robot, model="internal", starts=2, seed=0).trajectory
    run = simulator.run(trajectory, simulator.default_controller(bandwidth_hz=DEMO_BANDWIDTH_HZ), periods=periods,
                        warmup_periods=1, seed=1)
    clean = run.measurements
    model = build_model(robot, "internal", SHAPED_EFFECTS)
    truth = dict(zip(model.base.names, model.base.to_base(simulator.true_theta(model))))
    for effect in simulator.joint_effects:
        if effect.name == "coulomb":
            truth.update({f"vc{joint + 1}": float(effect.smoothing) for joint in range(robot.n_joints)})
    differentiation = FourierDifferentiation(frequency_hz=trajectory.frequency_hz, harmonics=harmonics, average=False)
    realise = noisy_encoder(clean, run.q, encoder_resolution(robot)) if encoder_phase else noisy(clean)
    return realise, model, truth, differentiation, clean.n_samples


def noisy_encoder(clean, q_true, resolution, std: float = TAU_STD):
    """``seed -> measurements`` with fresh torque noise and a fresh encoder phase: the true positions
    shifted by a uniform fraction of a count before quantisation (and back), so each realisation's
    quantisation error is drawn anew, as the motion of repeated experiments differs by more than a
    count (the derivatives are then derived per realisation)."""
    def realise(seed: int):
        generator = np.random.default_rng(seed)
        noise = generator.normal(0.0, std, clean.tau.shape)
        phase = generator.uniform(-0.5, 0.5, resolution.shape) * resolution
        q = np.round((q_true + phase) / resolution) * resolution - phase
        return replace(clean, q=q, tau=clean.tau + noise)
    return realise


class FourierOperator:
    """The demo's derivatives (a Fourier fit over all periods on the record's own time stamps, then
    the hold compensation: ``fill_derivatives(m, FourierDifferentiation(average=False), held_torques=True)``)
    as the linear map of ``q`` they are on a fixed time grid: the fit's pseudo-inverse is formed once,
    so a realisation with its own quantisation error costs two small products instead of a
    15 000 x 501 least-squares solve (checked against ``fill_derivatives`` on the first record)."""

    def __init__(self, t, frequency_hz: float, harmonics: int):
        elapsed = t - t[0]  # as estimation.preprocessing.fourier_series.fit_series: phases from the record's start
        design = design_matrix(elapsed, frequency_hz, harmonics)
        omega = 2 * np.pi * frequency_hz * np.arange(1, harmonics + 1)
        phase = np.outer(elapsed, omega)
        zero = np.zeros((elapsed.shape[0], 1))
        with single_threaded_blas():
            self.pinv = np.linalg.pinv(design)
        self.rows = (design, np.hstack([zero, np.cos(phase), np.sin(phase)]),
                     np.hstack([zero, -np.sin(phase) * omega, np.cos(phase) * omega]))

    def __call__(self, q):
        coefficients = self.pinv @ q
        return tuple(_later(rows @ coefficients) for rows in self.rows)


def _later(values):
    """``estimation.preprocessing.differentiation.compensate_hold``'s half-sample shift."""
    following = np.vstack([values[1:], 2 * values[-1:] - values[-2:-1]])
    return (values + following) / 2


def shaped_estimator(model, differentiation, covariance: str = "hac"):
    """``measurements -> EstimateDraw``: the demo's preprocessing (torques as recorded), then
    ``identify`` with the shaped effects (variable projection), base and shape parameters.

    The derivatives come from ``q`` only: by :class:`FourierOperator`, built (and checked against
    ``fill_derivatives``) on the first record.
    """
    built: list = []
    lock = threading.Lock()

    def estimate(measurements):
        with lock:
            if not built:
                with single_threaded_blas():
                    reference = fill_derivatives(measurements, differentiation, held_torques=True)
                operator = FourierOperator(measurements.t, differentiation.frequency_hz, differentiation.harmonics)
                for name, mine in zip(("q", "dq", "ddq"), operator(measurements.q)):
                    theirs = getattr(reference, name)
                    if not np.allclose(mine, theirs, rtol=0, atol=1e-9 * np.max(np.abs(theirs))):
                        raise AssertionError(f"FourierOperator's {name} differs from fill_derivatives'")
                built.append((operator, reference))
        operator, reference = built[0]
        q, dq, ddq = operator(measurements.q)
        prepared = replace(reference, q=q, dq=dq, ddq=ddq, tau=measurements.tau)
        return identification_draw(identify(model, prepared, covariance=covariance))
    return estimate


def groups(names):
    """Parameters by group: rigid body, viscous, Coulomb, offsets, smoothing velocities."""
    prefixes = {"viscous": "fv", "coulomb": "fc", "offset": "off", "smoothing": "vc"}
    out = {group: [name for name in names if name.startswith(prefix)] for group, prefix in prefixes.items()}
    effects = {name for members in out.values() for name in members}
    return {"rigid body": [name for name in names if name not in effects], **{k: v for k, v in out.items() if v}}


def report(label: str, result, seconds: float) -> None:
    coverage = result.coverage()
    print(f"{label}: {result.realisations} realisations in {seconds:.0f} s; overall coverage {result.overall():.3f}")
    for group, members in groups(result.names).items():
        print(f"  {group:11s} mean {np.mean([coverage[n] for n in members]):.3f} "
              f"(min {min(coverage[n] for n in members):.3f}, {len(members)} parameters)")
    worst = sorted(coverage, key=coverage.get)[:5]
    print("  lowest: " + ", ".join(f"{n} {coverage[n]:.3f} (bias {result.bias_sigmas()[n]:+.2f} sd, "
                                   f"std ratio {result.std_ratio()[n]:.2f})" for n in worst))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--realisations", type=int, default=200)
    parser.add_argument("--model", choices=("linear", "shaped", "both"), default="both",
                        help="linear: the smoothing known (least squares); shaped: coulomb:tanh by identify")
    parser.add_argument("--covariance", choices=("hac", "classical", "both"), default="both")
    parser.add_argument("--random-trajectory", action="store_true", help="linear: skip the design (a random Fourier motion)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--harmonics", type=int, default=300,
                        help="linear: harmonics of the Fourier differentiation (the demo's 15 leave a deterministic error)")
    parser.add_argument("--periods", type=int, default=3, help="shaped: periods of the record (the demo's 3)")
    parser.add_argument("--encoder-phase", action="store_true",
                        help="shaped: draw the quantisation error anew in each realisation (noisy_encoder)")
    args = parser.parse_args()
    methods = ("classical", "hac") if args.covariance == "both" else (args.covariance,)
    settings = []
    if args.model in ("linear", "both"):
        def linear():
            clean, model, truth, differentiation = demo_setting(design=not args.random_trajectory,
                                                                harmonics=args.harmonics)
            return noisy(clean), model, truth, differentiation, clean.n_samples
        settings.append(("linear", linear, linear_estimator))
    if args.model in ("shaped", "both"):
        label = "shaped, encoder phase drawn" if args.encoder_phase else "shaped"
        settings.append((label, lambda: shaped_demo_setting(periods=args.periods, encoder_phase=args.encoder_phase),
                         shaped_estimator))
    with ThreadPoolExecutor(max_workers=args.workers) as executor:
        for label, setting, estimator in settings:
            start = time.perf_counter()
            realise, model, truth, differentiation, samples = setting()
            print(f"{label} set-up {time.perf_counter() - start:.0f} s: {samples} samples, "
                  f"{len(truth)} parameters checked")
            for method in methods:
                start = time.perf_counter()
                result = monte_carlo_coverage(realise, estimator(model, differentiation, method), truth,
                                              realisations=args.realisations, executor=executor)
                report(f"{label} {method}", result, time.perf_counter() - start)


if __name__ == "__main__":
    main()
