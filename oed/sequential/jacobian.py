"""The sensitivity of an identified model's prediction to every parameter it estimated, shapes included.

An identified model predicts ``ŷ = Y_b(q, q̇, q̈; s) θ`` (PUMA paper, eq. 13, with the shaped columns of
:mod:`estimation.identification.shaped` at the fitted shapes ``s``). Its parameters are ``φ = (θ, s)``: the
base parameters and the shape parameters. Linearised at the estimate ``φ̂`` the prediction of one sample
changes by ``J(q, q̇, q̈) δφ`` with ``J = [Y_b(·; ŝ), ∂(Y_b(·; s) θ̂)/∂s |ŝ]`` (``m x (r + n_s)``), the
Jacobian a Gauss–Newton step of the nonlinear least-squares fit uses. :class:`ModelJacobian` builds ``J``
once as a named CasADi function of one sample from the model's own CasADi graphs (the rigid-body base
regressor and each shaped effect's columns, differentiated exactly in ``s``), with each channel's row
divided by its noise standard deviation ``σ_c`` (the model's residual variance per channel), so that
``Σ_k J_kᵀ J_k`` is the Fisher information of a record (Walter and Pronzato, *Identification of Parametric
Models from Experimental Data*, Springer 1997, section 6.1).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import casadi
import numpy as np
from numpy.typing import NDArray

from dynamics.effects.shaped import shape_parameters
from dynamics.effects.specs import effect_spec
from dynamics.models import check_states
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.shaped import shaped_blocks

__all__ = ["ModelJacobian", "SequentialDesignError", "model_jacobian"]


class SequentialDesignError(ValueError):
    """A sequential or discriminating design asked of input that does not fit together."""


@dataclass(frozen=True)
class ModelJacobian:
    """The noise-weighted Jacobian of an identified model's prediction in its parameters (module docstring).

    Attributes
    ----------
    function
        ``sample_jacobian(q, dq, ddq) -> J`` (``m x p``): one sample's weighted Jacobian, CasADi.
    prediction
        ``sample_prediction(q, dq, ddq) -> y`` (``m``): one sample's prediction, weighted alike.
    names
        The ``p`` parameter names: the base parameters, then the shape parameters.
    estimate
        ``(p,)`` the estimate ``φ̂ = (θ̂, ŝ)`` at which ``J`` is taken.
    effects
        Per effect of the model (its name and its spec), the names of its parameters among ``names``:
        its coefficients that are base parameters of their own, and its shape parameters.
    noise_std
        ``(m,)`` the channels' noise standard deviations ``σ_c`` dividing ``J``'s rows.
    """

    function: casadi.Function
    prediction: casadi.Function
    names: tuple[str, ...]
    estimate: NDArray[np.float64]
    effects: tuple[tuple[str, str, tuple[str, ...]], ...]
    noise_std: NDArray[np.float64]

    @property
    def n_parameters(self) -> int:
        return len(self.names)

    def evaluate(self, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray[np.float64]:
        """``(N, m, p)`` weighted Jacobians at the samples (``(N, n)`` states each)."""
        n = self.function.size1_in(0)
        q, dq, ddq = check_states(n, q, dq, ddq)
        mapped = self.function.map(q.shape[0])
        stacked = np.asarray(mapped(q.T, dq.T, ddq.T))  # (m, N p), sample-major blocks
        m, p = self.function.size1_out(0), self.n_parameters
        return stacked.reshape(m, q.shape[0], p).transpose(1, 0, 2)

    def information(self, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray[np.float64]:
        """``Σ_k J_kᵀ J_k`` over the samples: the Fisher information of a record along this motion."""
        J = self.evaluate(q, dq, ddq).reshape(-1, self.n_parameters)
        return J.T @ J

    def indices(self, names: Sequence[str]) -> tuple[int, ...]:
        """Positions of ``names`` among :attr:`names`."""
        return tuple(self.names.index(name) for name in names)


def _effect_parameters(model: IdentifiedModel, shape_names: Sequence[str]) -> tuple[tuple[str, str, tuple[str, ...]], ...]:
    """Per effect: name, spec, and its parameters that are base parameters of their own or shapes."""
    identification = model.model
    own = {name for name, expression in zip(identification.base.names, identification.base.expressions)
           if expression.strip() == name}
    entries = []
    for effect in identification.effects:
        names = [name for name in effect.parameter_names(model.robot) if name in own]
        shapes = [parameter.name for parameter in shape_parameters(effect, model.robot) if parameter.name in shape_names]
        entries.append((effect.name, effect_spec(effect), tuple(names + shapes)))
    return tuple(entries)


def model_jacobian(model: IdentifiedModel, noise_std: NDArray[np.float64] | None = None) -> ModelJacobian:
    """The :class:`ModelJacobian` of ``model`` at its estimate, weighted by its channels' residual variance
    (or by ``noise_std``, ``(m,)``: another model's, when two are compared).

    Raises
    ------
    SequentialDesignError
        When a channel's variance is not positive and finite (no noise level to weight it by).
    """
    if not isinstance(model, IdentifiedModel):
        raise TypeError(f"model must be an IdentifiedModel, got {type(model).__name__}")
    variance = np.asarray(model.file.channel_variance if noise_std is None else np.square(noise_std), dtype=float)
    bad = [channel for channel, value in zip(model.channels, variance) if not (np.isfinite(value) and value > 0)]
    if bad:
        raise SequentialDesignError(f"the model file gives channel(s) {', '.join(bad)} no positive noise variance: "
                                    "their information cannot be weighted")
    identification = model.model
    n = model.robot.n_joints
    q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
    Y = identification.base_regressor(q, dq, ddq)
    columns = [Y[:, index] for index in range(identification.n_base)]
    blocks, replaced = shaped_blocks(identification)
    shape_names = [parameter.name for block in blocks for parameter in block.parameters]
    shape = casadi.SX.sym("shape", len(shape_names))
    start, position = 0, 0
    for block in blocks:
        block_columns = block.columns_function.function(q, dq, ddq, shape[start:start + block.n_shape])
        C = casadi.reshape(block_columns, block.n_linear, identification.n_channels).T  # vec(Cᵀ) -> C (m x k)
        for offset, index in enumerate(replaced[position:position + block.n_linear]):
            columns[index] = C[:, offset]
        start += block.n_shape
        position += block.n_linear
    regressor = casadi.horzcat(*columns)
    theta = casadi.DM(np.asarray(model.theta, dtype=float))
    shape_values = np.array([model.shape[name] for name in shape_names], dtype=float)
    predicted = casadi.mtimes(regressor, theta)
    jacobian = casadi.horzcat(regressor, casadi.jacobian(predicted, shape))
    noise_std = np.sqrt(variance)
    weight = casadi.diag(casadi.DM(1.0 / noise_std))
    at_estimate = casadi.Function("shaped_jacobian", [q, dq, ddq, shape],
                                  [casadi.mtimes(weight, jacobian), casadi.mtimes(weight, predicted)])
    weighted_jacobian, weighted_prediction = at_estimate(q, dq, ddq, casadi.DM(shape_values))
    function = casadi.Function("sample_jacobian", [q, dq, ddq], [casadi.densify(weighted_jacobian)],
                               ["q", "dq", "ddq"], ["J"])
    prediction = casadi.Function("sample_prediction", [q, dq, ddq], [casadi.densify(weighted_prediction)],
                                 ["q", "dq", "ddq"], ["y"])
    names = tuple(identification.base.names) + tuple(shape_names)
    return ModelJacobian(function, prediction, names, np.concatenate([np.asarray(model.theta, float), shape_values]),
                         _effect_parameters(model, shape_names), noise_std)
