"""Shaped effects: the spec grammar, variable projection against known shapes, derivatives, bad input."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import ClassVar

import casadi
import numpy as np
import pytest

from dynamics.effects.linear import CoulombFriction, parse_effects
from dynamics.models import ModelKind, build_model
from dynamics.robots import load_robot
from dynamics.effects.shaped import (
    PositionRipple,
    ShapeBoundsError,
    ShapedPerJointEffect,
    ShapeKind,
    ShapeParameter,
    SigmoidFriction,
    TanhCoulombFriction,
)
from estimation.identification.fit import identify
from estimation.estimators.effect_blocks import Block, NoRowsError, ShapeSearchError, States
from estimation.estimators.separable_least_squares import FixedPart
from estimation.estimators.variable_projection import fit_shapes
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


@pytest.fixture(scope="module")
def tanh_records(robot):
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(smoothing=0.03)))
    theta = true_parameters(truth, seed=0, coulomb=[8.0, 5.0, 3.0])
    noise = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
    return [simulate(truth, theta, random_fourier(robot, seed=seed), noise=noise, seed=seed, rate_hz=250, periods=2)
            for seed in (3, 4)]


def test_spec_grammar_selects_the_shaped_variants():
    effects = parse_effects("viscous,coulomb:tanh,stribeck:velocity,sigmoid,ripple")
    assert [getattr(effect, "spec", effect.name) for effect in effects] == [
        "viscous", "coulomb:tanh", "stribeck:velocity", "sigmoid", "ripple"]
    assert parse_effects("coulomb:sign") == parse_effects("coulomb")
    with pytest.raises(ValueError, match="unknown effect 'coulomb:cubic'"):
        parse_effects("coulomb:cubic")


def test_identify_estimates_the_smoothing_velocity_with_its_std(robot, tanh_records):
    train, validate = tanh_records
    result = identify(build_model(robot, "internal", "viscous,coulomb:tanh"), train, validate)
    shapes = {value.name: value for value in result.shapes}
    assert set(shapes) == {"vc1", "vc2", "vc3"}
    for value in shapes.values():
        assert abs(value.value - 0.03) < 4 * value.std and value.std < 0.003
    values = dict(zip(result.estimate.names, result.estimate.values))
    assert values["fc1"] == pytest.approx(8.0, abs=0.05) and values["fc3"] == pytest.approx(3.0, abs=0.05)
    document = result.to_dict()
    assert set(document["shape"]) == set(document["shape_std"]) == {"vc1", "vc2", "vc3"}
    assert max(result.validation.mse.values()) < 1.3 * 0.2**2


def test_shape_derivatives_match_finite_differences(robot):
    block = Block(ModelKind.INTERNAL, robot, SigmoidFriction(joints=(1,)), 3)
    generator = np.random.default_rng(1)
    states = States(*(generator.normal(scale=0.3, size=(50, 3)) for _ in range(3)))
    shape = np.array([30.0, 0.05])
    _, derivative = block.evaluate(states, shape, jacobian=True)
    for j, step in enumerate((1e-4, 1e-7)):
        up, down = shape.copy(), shape.copy()
        up[j] += step
        down[j] -= step
        numeric = (block.evaluate(states, up) - block.evaluate(states, down)) / (2 * step)
        np.testing.assert_allclose(derivative[j], numeric, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("bounds", [((0.5, 0.1),), ((0.1, 0.1),), ((0.0, 1.0),), ((0.1, np.inf),)])
def test_empty_or_reversed_shape_bounds_are_named(bounds):
    with pytest.raises(ShapeBoundsError, match="vc"):
        TanhCoulombFriction(joints=(0,), bounds=bounds)
    with pytest.raises(ShapeBoundsError):
        ShapeParameter("n", 3.0, 2.0, (2.5,))


def test_starts_outside_the_bounds_are_named():
    with pytest.raises(ShapeBoundsError, match="outside the bounds"):
        PositionRipple(joints=(0,), bounds=((2.0, 5.0),), starts=((7.0,),))


@dataclass(frozen=True)
class _Broken(ShapedPerJointEffect):
    """A user's law that is NaN for every shape."""

    name: ClassVar[str] = "broken"
    linear: ClassVar[tuple[str, ...]] = ("b",)
    kinds: ClassVar[tuple[ShapeKind, ...]] = (ShapeKind("s", 1.0, 2.0, (1.5,)),)

    def law(self, q, dq, ddq, shape):
        return [dq * casadi.sqrt(-shape[0])]


@dataclass(frozen=True)
class _Flat(ShapedPerJointEffect):
    """A user's law whose shape the data cannot see: the search must fail by name."""

    name: ClassVar[str] = "flat"
    linear: ClassVar[tuple[str, ...]] = ("g",)
    kinds: ClassVar[tuple[ShapeKind, ...]] = (ShapeKind("s", 1.0, 2.0, (1.5,)),)

    def law(self, q, dq, ddq, shape):
        return [casadi.tanh(dq / 0.1) + 1e-300 * shape[0]]


@dataclass(frozen=True)
class _Silent(ShapedPerJointEffect):
    """A user's law whose columns are zero everywhere."""

    name: ClassVar[str] = "silent"
    linear: ClassVar[tuple[str, ...]] = ("z",)
    kinds: ClassVar[tuple[ShapeKind, ...]] = (ShapeKind("s", 1.0, 2.0, (1.5,)),)

    def law(self, q, dq, ddq, shape):
        return [0 * shape[0]]


def test_a_failing_shape_search_is_named(robot, tanh_records):
    train, _ = tanh_records
    with pytest.raises(ShapeSearchError, match="not determined by these data"):
        identify(build_model(robot, "internal", ("viscous", _Flat(joints=(0,)))), train)
    with pytest.raises(ValueError, match="NaN or inf at generic states"):
        build_model(robot, "internal", ("viscous", _Broken(joints=(0,))))


def test_an_effect_without_rows_is_named(robot, tanh_records):
    train, _ = tanh_records
    with pytest.raises(NoRowsError, match="no rows"):
        Block(ModelKind.INTERNAL, robot, _Silent(joints=(0,)), 3)
    with pytest.raises(NoRowsError, match="no rows"):
        Block(ModelKind.EXTERNAL, robot, TanhCoulombFriction(joints=(0,)), 6)


def _cli(tmp_path, records, *extra):
    from oed.cli import main

    for name, data in zip(("train.csv", "val.csv"), records):
        data.write(tmp_path / name)
    return main(["identify", "--robot", "puma560", "--joints", "3", "--data", str(tmp_path / "train.csv"),
                 "--validate", str(tmp_path / "val.csv"), "--out", str(tmp_path / "result.json"), *extra])


def test_identify_cli_reports_shape_values(tmp_path, tanh_records, capsys):
    assert _cli(tmp_path, tanh_records, "--friction", "viscous,coulomb:tanh") == 0, capsys.readouterr().err
    document = json.loads((tmp_path / "result.json").read_text())
    assert set(document["shape"]) == {"vc1", "vc2", "vc3"} and set(document["shape_std"]) == {"vc1", "vc2", "vc3"}
    assert {"parameters", "validation", "effects"} <= set(document)
    assert "shape of coulomb:tanh" in capsys.readouterr().out


def test_identify_cli_bad_shaped_input_exits_2_and_writes_nothing(tmp_path, tanh_records, capsys, monkeypatch):
    assert _cli(tmp_path, tanh_records, "--friction", "viscous,coulomb:tanh", "--model", "external") == 2
    assert "has no rows in the external model" in capsys.readouterr().err
    assert not (tmp_path / "result.json").exists()

    import estimation.identification.shaped as module

    def failing(*args, **kwargs):
        raise ShapeSearchError("shape search for vc1: the columns are non-finite or singular at every start")

    monkeypatch.setattr(module, "fit_shapes", failing)
    assert _cli(tmp_path, tanh_records, "--friction", "viscous,coulomb:tanh") == 2
    assert "oed identify: error: shape search for vc1" in capsys.readouterr().err
    assert not (tmp_path / "result.json").exists()


def test_a_screening_fit_stops_where_the_full_fit_does_and_extended_columns_keep_their_gram(robot, tanh_records):
    train, _ = tanh_records
    model = build_model(robot, "internal", "viscous")
    fixed = FixedPart.from_arrays(model.evaluate_base(train.q, train.dq, train.ddq), train.channels(model.channels))
    block = Block(ModelKind.INTERNAL, robot, parse_effects("coulomb:tanh")[0], len(model.channels))
    states, weights = States(train.q, train.dq, train.ddq), np.ones(len(model.channels))
    screening = fit_shapes(fixed, [block], states, weights, covariance="none")
    full = fit_shapes(fixed, [block], states, weights, covariance="white")
    assert np.array_equal(screening.shape, full.shape) and np.array_equal(screening.theta, full.theta)
    assert screening.rss == full.rss and screening.cov.shape == full.cov.shape and np.all(np.isnan(screening.cov))
    columns = block.evaluate(states, screening.shape)
    extended = fixed.extended(columns, block.rows)
    Y = np.zeros((train.n_samples, len(model.channels), block.n_linear))
    Y[:, list(block.rows), :] = columns
    direct = FixedPart.from_arrays(np.concatenate([model.evaluate_base(train.q, train.dq, train.ddq), Y], axis=2),
                                   train.channels(model.channels))
    for name in ("A", "y", "power"):
        assert np.array_equal(getattr(extended, name), getattr(direct, name)), name
    for name in ("gram", "moment"):  # the old block kept, the new one formed on its channels alone: to rounding
        difference = np.abs(getattr(extended, name) - getattr(direct, name))
        assert np.max(difference) <= 1e-13 * np.max(np.abs(getattr(direct, name))), name


def test_states_are_contiguous_copies_and_refuse_a_missing_derivative():
    q = np.asfortranarray(np.arange(12.0).reshape(4, 3))
    states = States(q, q[:, ::-1], q * 2)
    assert all(array.flags.c_contiguous for array in (states.q, states.dq, states.ddq))
    np.testing.assert_array_equal(states.dq, q[:, ::-1])
    with pytest.raises(ValueError, match="the states need ddq"):
        States(q, q, None)


def test_a_shape_held_at_its_bound_leaves_the_others_a_newton_step(robot, tanh_records, monkeypatch):
    """Joint 1's smoothing bounded above its truth (0.03): its optimum is the lower bound. The step of the other
    shapes leaves it out (projected Newton); the step of every shape, clipped, ran to the iteration limit and
    stopped higher. A search that reaches no bound takes the same steps as before, to the last bit."""
    import estimation.estimators.variable_projection as variable_projection

    train, _ = tanh_records
    model = build_model(robot, "internal", "viscous")
    fixed = FixedPart.from_arrays(model.evaluate_base(train.q, train.dq, train.ddq), train.channels(model.channels))
    states, weights = States(train.q, train.dq, train.ddq), np.ones(len(model.channels))

    def fits(first_bounds):
        blocks = [Block(ModelKind.INTERNAL, robot, TanhCoulombFriction(joints=(joint,), bounds=bounds), 3)
                  for joint, bounds in enumerate((first_bounds, None, None))]
        return fit_shapes(fixed, blocks, states, weights, starts=np.array([[0.5, 0.5, 0.5]]), covariance="none")

    held, free = fits(((0.1, 2.0),)), fits(None)
    monkeypatch.setattr(variable_projection._ShapeSearch, "free", lambda self, u, gradient: None)  # the clipped step
    clipped, free_clipped = fits(((0.1, 2.0),)), fits(None)
    assert held.shape[0] == pytest.approx(0.1, rel=1e-12) and clipped.shape[0] == pytest.approx(0.1, rel=1e-12)
    assert held.iterations < 20 and clipped.iterations == 60
    assert held.rss < clipped.rss
    assert np.allclose(held.shape[1:], 0.03, rtol=0.05)
    assert free.iterations < 60 and np.array_equal(free.shape, free_clipped.shape) and free.rss == free_clipped.rss
    assert np.array_equal(free.theta, free_clipped.theta)


def test_the_rounds_predict_in_the_regressor_they_were_given_bit_for_bit(robot, tanh_records, monkeypatch):
    """``fit_shaped_model`` writes each round's shaped columns into its own base regressor rather than a copy, and a
    prediction without one into the regressor it evaluates (issue 34's cost): the predictions and the fit are those
    of the copy, bit for bit."""
    from estimation.identification import shaped as shaped_module

    train, _ = tanh_records
    model = build_model(robot, "internal", "viscous,coulomb:tanh")
    fit, estimate = shaped_module.fit_shaped_model(model, train)
    base = model.evaluate_base(train.q, train.dq, train.ddq)
    work = base.copy()
    kept = list(fit.kept)
    for rewritten in (False, True, True):  # written three times: the same values, the kept columns untouched
        # rewritten: the shaped columns written again on their blocks' rows alone, the rest zero from the first write
        np.testing.assert_array_equal(fit.predict(train, work, overwrite=True, rewritten=rewritten),
                                      fit.predict(train, base))
        np.testing.assert_array_equal(work[:, :, kept], base[:, :, kept])
        np.testing.assert_array_equal(work, fit.regressor(train))
    np.testing.assert_array_equal(base, model.evaluate_base(train.q, train.dq, train.ddq))  # the copy path: untouched
    np.testing.assert_array_equal(fit.predict(train), fit.predict(train, base))  # evaluated: written in place
    taken = FixedPart.from_arrays(np.take(base, kept, axis=2), train.tau)  # the fixed part from a C-ordered copy
    indexed = FixedPart.from_arrays(np.ascontiguousarray(base[:, :, kept]), train.tau)
    for name in ("own", "where"):
        for mine, theirs in zip(getattr(taken, name), getattr(indexed, name)):
            np.testing.assert_array_equal(mine, theirs)
    for name in ("y", "gram", "moment", "power"):
        np.testing.assert_array_equal(getattr(taken, name), getattr(indexed, name))
    copied = shaped_module.ShapedFit.predict
    monkeypatch.setattr(shaped_module.ShapedFit, "predict",
                        lambda self, measurements, base=None, overwrite=False, rewritten=False:
                        copied(self, measurements, base))
    reference_fit, reference = shaped_module.fit_shaped_model(model, train)
    np.testing.assert_array_equal(fit.fit.shape, reference_fit.fit.shape)
    for name in ("values", "cov", "residuals", "weights"):
        np.testing.assert_array_equal(getattr(estimate, name), getattr(reference, name))
