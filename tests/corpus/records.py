"""A corpus case simulated and diagnosed in the library, and the outcome the tests check.

The records: :func:`dynamics.simulation.synthetic.simulate` (declared model ``Y θ`` of a 3-joint PUMA 560, Fourier motion at
the case's rate, 250 Hz by default, two 5 s periods: 2500 samples a record) plus each true term's columns at its true shape times its
coefficients; a delay moves the recorded motion ahead of the torques. From positions only, the derivatives are
made as a user gets them: the preprocessing chosen by held-out evidence on the training record
(:func:`estimation.identification.preprocessing_choice.choose_by_evidence`), both records prepared with it.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache, lru_cache
from typing import Any

import numpy as np

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, ModelKind, build_model
from dynamics.robots import load_robot
from estimation.diagnosis.results import Diagnosis
from estimation.diagnosis.search import diagnose
from estimation.estimators.effect_blocks import Block, States
from estimation.identification.fit import identify
from estimation.identification.preprocessing_choice import choose_by_evidence
from estimation.preprocessing.plan import PreprocessingWarning, prepare
from estimation.uncertainty.noise_floor import NoiseFloor, noise_floor
from tests.corpus.cases import NOISE, Case
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier

PERIODS = 2


@lru_cache(maxsize=1)
def robot():
    return load_robot("puma560", joints=3)


def declared_model() -> IdentificationModel:
    return build_model(robot(), "internal", "viscous")


def true_model(case: Case) -> IdentificationModel:
    """The declared model with the case's true laws (their shapes estimated by a fit that knows them)."""
    return build_model(robot(), "internal", ("viscous", *(term.effect for term in case.terms)))


def simulated(case: Case, seed: int, noise_seed: int | None = None) -> Measurements:
    """One record of the case (``seed`` picks the trajectory and, unless ``noise_seed`` is given, the noise)."""
    declared = declared_model()
    theta = true_parameters(declared, seed=0)
    trajectory = random_fourier(robot(), seed=seed)
    noise = {channel: NOISE for channel in declared.channels}
    data = simulate(declared, theta, trajectory, rate_hz=case.rate_hz, periods=PERIODS, noise=noise,
                    seed=seed if noise_seed is None else noise_seed)
    tau = data.tau.copy()
    states = States(data.q, data.dq, data.ddq)
    for term in case.terms:
        block = Block(ModelKind.INTERNAL, robot(), term.effect, declared.n_channels)
        tau[:, list(block.rows)] += block.evaluate(states, np.array(term.shape, dtype=float)) @ np.array(term.coefficients)
    for exotic in case.exotic:
        tau[:, exotic.joint] += exotic.law(data.q[:, exotic.joint], data.dq[:, exotic.joint], data.t)
    data = dataclasses.replace(data, tau=tau)
    if case.delay:
        q, dq, ddq = trajectory.evaluate(data.t + case.delay)  # the recorded motion runs ahead of the torques
        data = dataclasses.replace(data, q=q, dq=dq, ddq=ddq)
    if case.derivatives == "positions":
        data = dataclasses.replace(data, dq=None, ddq=None)
    return data


def records(case: Case) -> tuple[Measurements, Measurements]:
    """Training and validation records, with derivatives (measured, or chosen by evidence on training)."""
    if case.repeat:  # the training motion again, with the other seed's noise
        train, validate = simulated(case, case.seeds[0]), simulated(case, case.seeds[0], noise_seed=case.seeds[1])
    else:
        train, validate = (simulated(case, seed) for seed in case.seeds)
    if case.derivatives == "positions":
        with warnings.catch_warnings():  # the detected fundamental is said to a user, not to the corpus
            warnings.simplefilter("ignore", PreprocessingWarning)
            choice = choose_by_evidence(declared_model(), train)
        train, validate = (prepare(data, choice.chosen) for data in (train, validate))
    return train, validate


def truth(case: Case) -> dict[str, float]:
    """The true value of every parameter of the case's terms (linear and shape), named as the diagnosis names them."""
    values: dict[str, float] = {}
    for term in case.terms:
        values.update(zip(term.effect.parameter_names(robot()), term.coefficients))
        shapes = getattr(term.effect, "shape_parameters", None)
        if shapes is not None:
            values.update(zip((parameter.name for parameter in shapes(robot())), term.shape))
    if case.delay:
        values["delay"] = case.delay
    return values


@dataclass(frozen=True)
class Outcome:
    """What the loop gave on a case: effects named, error over floor and over a known-law fit, estimates' errors."""

    named: frozenset[tuple[str, str]]
    over_floor: dict[str, float]
    over_known_law: dict[str, float]
    sigmas: dict[str, float]

    def summary(self) -> str:
        found = ", ".join(sorted(f"{spec}@{channel}" for spec, channel in self.named)) or "nothing"
        floor = "/".join(f"{value:.2f}" for value in self.over_floor.values())
        known = "/".join(f"{value:.2f}" for value in self.over_known_law.values()) or "-"
        worst = max(self.sigmas.items(), key=lambda item: item[1], default=None)
        estimate = "-" if worst is None else f"{worst[0]} {worst[1]:.1f} sd"
        return f"named {found}; after/floor {floor}; after/known law {known}; worst estimate {estimate}"


def named_pairs(diagnosis: Diagnosis) -> frozenset[tuple[str, str]]:
    return frozenset((effect.spec or effect.name, channel) for effect in diagnosis.effects for channel in effect.channels)


def estimate_errors(diagnosis: Diagnosis, true_values: dict[str, float]) -> dict[str, float]:
    """``|estimate − truth| / std`` of every true parameter the diagnosis named (linear and shape)."""
    errors = {}
    for effect in diagnosis.effects:
        pairs = list(zip(effect.parameters, effect.values, effect.std))
        pairs += [(name, value, effect.shape_std.get(name, 0.0)) for name, value in effect.shape.items()]
        for name, value, std in pairs:
            if name in true_values:
                errors[name] = abs(value - true_values[name]) / std if std > 0 else float("inf")
    return errors


def outcome(case: Case, diagnosis: Diagnosis, train: Measurements, validate: Measurements) -> Outcome:
    after = diagnosis.after.validation.mse
    over_known = {}
    if not case.exotic:  # no model knows an exotic law
        reference = identify(true_model(case), train, validate, delay=case.delay or None)
        over_known = {channel: value / reference.validation.mse[channel] for channel, value in after.items()}
    return Outcome(named_pairs(diagnosis), {channel: value / NOISE**2 for channel, value in after.items()},
                   over_known, estimate_errors(diagnosis, truth(case)))


def validation_floor(case: Case) -> NoiseFloor | None:
    """From positions only, the noise floor of the validation record as recorded, before its preprocessing (as
    ``oed diagnose`` computes it from the file); with measured derivatives the diagnosis estimates it itself."""
    if case.derivatives != "positions":
        return None
    seed, noise_seed = (case.seeds[0], case.seeds[1]) if case.repeat else (case.seeds[1], None)
    return noise_floor(simulated(case, seed, noise_seed), declared_model().channels)


def run(case: Case, *, candidates: Iterable | None = None, **options: Any) -> tuple[Diagnosis, Outcome]:
    """The case diagnosed (``options``: more keywords of :func:`~estimation.diagnosis.search.diagnose`).

    With the default candidates and options the run is deterministic and read-only for its callers (frozen results),
    so it is made once per test process and shared: ``test_library_cases`` and ``test_one_statistic`` check the same
    diagnoses of the same cases."""
    if candidates is None and not options:
        return default_run(case)
    return diagnosed(case, candidates=candidates, **options)


@cache
def default_run(case: Case) -> tuple[Diagnosis, Outcome]:
    """:func:`run` with the default candidates and options, once per case and process (about 1.4 MB each)."""
    return diagnosed(case)


def diagnosed(case: Case, *, candidates: Iterable | None = None, **options: Any) -> tuple[Diagnosis, Outcome]:
    """The case simulated and diagnosed anew (:func:`run` without the cache)."""
    train, validate = records(case)
    diagnosis = diagnose(declared_model(), train, validate, candidates=candidates, noise_floor=validation_floor(case),
                         **options)
    return diagnosis, outcome(case, diagnosis, train, validate)


def matches(expected: frozenset[tuple[str, str]], found: frozenset[tuple[str, str]],
            allowed: frozenset[tuple[str, str]] = frozenset()) -> bool:
    """Every expected pair named (``a|b``: either spec) and nothing else but what ``allowed`` lets be named."""
    def accepts(pattern: tuple[str, str], pair: tuple[str, str]) -> bool:
        return pair[1] == pattern[1] and pair[0] in pattern[0].split("|")

    return (all(any(accepts(pattern, pair) for pair in found) for pattern in expected)
            and all(any(accepts(pattern, pair) for pattern in expected | allowed) for pair in found))
