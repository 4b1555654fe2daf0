"""A per-channel sample mask: a sample whose reading on one channel is no measurement (a clipped torque sensor, a
force plate past its range) leaves that channel only, not the whole row.

The mask travels with the data as NaN in the measured channels (``tau``, ``wrench``) of
:class:`~dynamics.measurements.Measurements`: the readers put it there (:func:`masked_channels`), the positions of
that sample stay for the derivatives, and every consumer takes a masked entry as absent:

* the fits drop the masked equations ``y_nc = Y_nc θ`` from the stacked system (:func:`masked_equations`: the
  regressor row and target zeroed, which removes them from the normal equations ``YᵀY θ = Yᵀy`` exactly), the
  other channels' equations of that sample staying in;
* the errors per channel are means over that channel's valid samples (:func:`channel_counts` says how many).

Nothing is copied nor passed over when nothing is masked: a channel's sum of squares is NaN exactly when it holds a
masked entry, so the consumers test the sums they take anyway (:func:`masked_columns`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements


def masked_channels(arrays: dict, found: NDArray[np.bool_]) -> dict:
    """``arrays`` (``tau``, ``wrench``: those present, in that order as ``found``'s columns) with the entries of
    ``found`` ``(N, k)`` masked (NaN); the other arrays as they are. Copies only the arrays with a masked entry."""
    masked, column = dict(arrays), 0
    for key in ("tau", "wrench"):
        values = arrays.get(key)
        if values is None:
            continue
        part = found[:, column:column + values.shape[1]]
        column += values.shape[1]
        if part.any():
            masked[key] = np.where(part, np.nan, values)
    return masked


def masked_columns(sums: NDArray[np.float64]) -> NDArray[np.bool_] | None:
    """The channels whose sum (of squares, of residuals: any sum taken over the samples) ``sums`` ``(m,)`` is NaN,
    i.e. that hold a masked sample; ``None`` when none does (the default path: no further work)."""
    nan = np.isnan(sums)
    return nan if nan.any() else None


def channel_counts(values: NDArray[np.float64]) -> NDArray[np.int_]:
    """``(m,)`` the valid (not masked) samples of each channel of ``values`` ``(N, m)``."""
    return np.sum(~np.isnan(values), axis=0)


def channel_mean(values: NDArray[np.float64], measured: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """``(m,)`` the mean of each channel of ``values`` ``(N, m)`` over its valid samples, those where ``measured``
    (``values`` when not given) is not masked: ``numpy.mean`` when nothing is masked (one pass), the masked channels'
    taken again without their masked samples (NaN for a channel without any valid sample). ``values`` NaN where
    ``measured`` is valid stays NaN (a prediction that failed is no mask)."""
    mean = np.mean(values, axis=0)
    masked = masked_columns(mean)
    if masked is not None:
        columns = values[:, masked]
        valid = ~np.isnan(columns if measured is None else measured[:, masked])
        with np.errstate(invalid="ignore", divide="ignore"):
            mean[masked] = np.where(valid, columns, 0.0).sum(axis=0) / valid.sum(axis=0)
    return mean


def masked_equations(Y: NDArray[np.float64], y: NDArray[np.float64]
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_] | None]:
    """``(Y, y, mask)`` of a stacked problem (``Y`` ``(N, m, r)``, ``y`` ``(N, m)``) with its masked equations (NaN in
    ``y``) zeroed in both (copies), ``mask`` ``(N, m)`` true where valid; ``(Y, y, None)`` as given when nothing is
    masked. A zeroed equation adds nothing to ``YᵀY`` nor ``Yᵀy`` and leaves a residual of exactly 0."""
    nan = np.isnan(y)
    if not nan.any():
        return Y, y, None
    Y = Y.copy()
    Y[nan] = 0.0
    return Y, np.where(nan, 0.0, y), ~nan


def masked_cells(values: NDArray[np.float64]) -> NDArray[np.bool_] | None:
    """``(N, m)`` the masked entries (NaN) of ``values``, ``None`` when there is none (one sum's test)."""
    if not np.isnan(np.sum(values)):
        return None
    return np.isnan(values)


def valid_sum(values: NDArray[np.float64], masked: NDArray[np.bool_] | None) -> NDArray[np.float64]:
    """``(m,)`` each channel's sum of ``values`` ``(N, m)`` over its entries not ``masked``
    (:func:`masked_cells` of the measurement; ``None``: all)."""
    if masked is None:
        return np.sum(values, axis=0)
    return np.sum(np.where(masked, 0.0, values), axis=0)


def masked_rows(values: NDArray[np.float64] | None) -> NDArray[np.bool_] | None:
    """``(N,)`` the samples of ``values`` ``(N, m)`` with a masked channel, ``None`` when there is none."""
    if values is None or not np.isnan(np.sum(values)):
        return None
    return np.isnan(values).any(axis=1)


def whole_rows(measurements: Measurements) -> Measurements:
    """``measurements`` without the samples where any channel is masked (the row-wise rule, for the passes that
    take a sample's channels together: the diagnosis's search, whose candidate columns have no per-channel mask),
    in its samples as recorded too; ``measurements`` itself when nothing is masked, or when it is not
    :class:`~dynamics.measurements.Measurements` at all (the caller's own check then names what it got)."""
    if not isinstance(measurements, Measurements):
        return measurements
    rows = _any_masked(measurements)
    if rows is not None:
        measurements = measurements.select(np.flatnonzero(~rows))
    recorded = measurements.recorded
    if recorded is None:
        return measurements
    kept = _any_masked(recorded)
    if kept is None:
        return measurements
    kept = np.flatnonzero(~kept)
    return replace(measurements, recorded=recorded.select(kept),
                   recorded_rows=None if measurements.recorded_rows is None else measurements.recorded_rows[kept])


def _any_masked(measurements: Measurements) -> NDArray[np.bool_] | None:
    parts = [found for found in (masked_rows(measurements.tau), masked_rows(measurements.wrench)) if found is not None]
    if not parts:
        return None
    return np.logical_or.reduce(parts)


#: random states at which a channel's share of the base regressor is judged (:func:`channel_only_parameters`)
STATES_JUDGED = 64


def channel_only_parameters(model, channels: list[str]) -> list[str]:
    """The base parameters of ``model`` (an :class:`~dynamics.models.IdentificationModel`) whose column is zero on
    every channel but ``channels`` at :data:`STATES_JUDGED` random states (positions uniform over a turn,
    velocities and accelerations standard normal, seeded): with those channels masked on every sample (a driven
    joint whose torque was not logged), no other equation holds them, and they cannot be identified (its own
    friction and offset always; inertial combinations that only its torque sees)."""
    others = [index for index, channel in enumerate(model.channels) if channel not in channels]
    generator = np.random.default_rng(0)
    n = model.robot.n_joints
    q = generator.uniform(-np.pi, np.pi, (STATES_JUDGED, n))
    dq, ddq = generator.standard_normal((STATES_JUDGED, n)), generator.standard_normal((STATES_JUDGED, n))
    Y = model.evaluate_base(q, dq, ddq)[:, others, :]
    seen = np.any(np.abs(Y) > 1e-12 * max(float(np.max(np.abs(Y))), 1.0), axis=(0, 1))
    return [name for name, found in zip(model.base.names, seen) if not found]
