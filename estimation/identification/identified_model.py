"""An identified model loaded from its file: predict with it along any motion or record.

::

    model = IdentifiedModel.load("result.json")          # or report.json, written by oed identify / diagnose
    tau = model.predict(q, dq, ddq)                       # (N, m) channels
    prediction = model.predict_record(record)            # a prepared record: the delay applied, 95 % bands
    evaluation = model.evaluate(["tomorrow.csv"])         # read, derive as the model's preprocessing says, compare

The prediction is ``ŷ = Y_b(q, q̇, q̈; s) θ`` (PUMA paper, eq. 13, with the shaped columns of
:mod:`estimation.identification.shaped` at the fitted shapes ``s``), along the motion moved by the
fitted delay (:mod:`estimation.preprocessing.delay`). Its 95 % prediction interval per sample and
channel is ``ŷ ± z √(y_bᵀ Σ_θ y_b + σ_c²)``: the parameters' covariance ``Σ_θ`` (the linear
coefficients'; for shaped effects it includes the shapes' uncertainty through the full Jacobian)
plus the channel's residual variance ``σ_c²`` on the training record, against its channels as recorded.

A model file that carries a payload (``oed payload``, :mod:`estimation.payload`) adds ``Y_k π`` to the
prediction, ``Y_k`` the ten standard-parameter columns of its link, and ``y_kᵀ Σ_π y_k`` to the band's variance
(the payload's covariance, independent of the robot model's).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.channels import is_joint_torque, torque_joint
from dynamics.effects.shaped import is_shaped
from dynamics.effects.specs import build_effects, effect_spec
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, build_model, check_states
from dynamics.runtime.output_files import save_figure
from dynamics.transmission_files import transmission_from_json
from estimation.data.channel_mask import channel_counts
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.motor_side import read_record_with_transmission
from estimation.data.rest import coulomb_combinations, drop_rest
from estimation.data.sampling_clock import on_regular_clock
from estimation.estimators.effect_blocks import States
from estimation.identification.model_file import ModelFile, ModelFileError, read_model_file
from estimation.identification.record_changes import RecordChanges, check_record_changes
from estimation.identification.shaped import shaped_blocks
from estimation.identification.subtracted_load import added_back, load_channels, subtracted_torque
from estimation.identification.training_range import UNKNOWN_RANGE, ExtrapolationWarning, RangeCheck

if TYPE_CHECKING:
    from matplotlib.figure import Figure
from estimation.identification.trivial_predictors import trivial_mse
from estimation.identification.validation import channel_mse
from estimation.preprocessing.delay import delayed
from estimation.preprocessing.plan import Preprocessing, best_filter, check_frequency, prepare_unseen
from estimation.uncertainty.floor_comparison import mse_over_floor
from estimation.uncertainty.noise_floor import NoiseFloorError, noise_floor, pooled_floor

__all__ = ["Z_95", "Evaluation", "IdentifiedModel", "Prediction", "alternative_names", "preprocessing_from_dict"]

#: the two-sided 95 % quantile of the normal distribution
Z_95 = 1.959963984540054


def preprocessing_from_dict(document: dict[str, Any] | None) -> Preprocessing:
    """The :class:`Preprocessing` whose :meth:`~Preprocessing.to_dict` gave ``document`` (measured when ``None``)."""
    if document is None:
        return Preprocessing("measured")
    fields = {key: document[key] for key in ("method", "frequency_hz", "harmonics", "frequency_source",
                                             "average_periods", "cutoff_hz", "trimmed_s", "decimation",
                                             "held_torques") if key in document}
    if "filter_order" in document:
        fields["order"] = int(document["filter_order"])
    if "velocity_from_positions" in document:
        fields["velocity_from_positions"] = bool(document["velocity_from_positions"])
    if document.get("time_base") == "regular":
        fields["time_base"] = "regular"
    return Preprocessing(**fields)


def recorded_stamps(t: NDArray[np.float64], segments: Sequence[Measurements],
                    stamped: Sequence[Measurements]) -> NDArray[np.float64]:
    """For each instant of ``t`` (of ``segments``, some on their regular clock), the stamp its sample was recorded
    with (``stamped``: the same segments at their stamps, row for row)."""
    stamp_of: dict[float, float] = {}
    for segment, original in zip(segments, stamped):
        if segment is not original:  # on its regular clock: one row of it a recorded row
            stamp_of.update(zip(segment.t.tolist(), original.as_recorded.t.tolist()))
    return np.array([stamp_of.get(instant, instant) for instant in t.tolist()])


@dataclass(frozen=True)
class _Entry:
    """One model of a model file: the file's own or one of its alternatives."""

    theta: Any
    cov: Any
    shape: Mapping[str, float]
    delay: float | None
    band_variance: NDArray[np.float64]
    validation_mse: Mapping[str, float] | None


def alternative_names(model_file: ModelFile) -> tuple[str, ...]:
    """The names ``--alternative`` takes for ``model_file``: its chosen model's, its alternatives', and
    ``consistent`` for a file with a consistent fit."""
    names = ([model_file.chosen] if model_file.chosen else []) + list(model_file.alternatives)
    if model_file.consistent_theta is not None and "consistent" not in names:
        names.append("consistent")
    return tuple(dict.fromkeys(names))


def _selected(model_file: ModelFile, name: str | None) -> tuple[str, _Entry]:
    """``(name, entry)`` of the model called ``name`` in ``model_file`` (``None``: the chosen one)."""
    chosen = model_file.chosen or "unconstrained"
    if name == "unconstrained":  # the unconstrained fit behind the choice (the consistent fit's start)
        name = chosen if chosen != "consistent" else model_file.method
    if name is None or name == chosen:
        return chosen, _Entry(model_file.theta, model_file.cov, model_file.shape, model_file.delay,
                              model_file.band_variance, model_file.reported_validation_mse)
    if name in model_file.alternatives:
        entry = model_file.alternatives[name]
        try:
            channels = model_file.channels
            recorded = entry.get("recorded_variance") or entry["channel_variance"]
            delay = entry.get("delay")
            return name, _Entry(np.asarray(entry["theta"], dtype=float), np.asarray(entry["cov"], dtype=float),
                                dict(entry.get("shape") or {}), None if delay is None else float(delay["value"]),
                                np.array([recorded[c] for c in channels], dtype=float), entry.get("validation_mse"))
        except (KeyError, TypeError) as error:
            raise ModelFileError(f"the model file's alternative {name!r} lacks or garbles {error}") from None
    if name == "consistent" and model_file.consistent_theta is not None:  # a file of an earlier release
        return name, _Entry(model_file.consistent_theta, model_file.consistent_cov, model_file.shape, model_file.delay,
                            model_file.band_variance, model_file.consistent_validation_mse)
    if name == "consistent":
        raise ModelFileError("the model file holds no physically consistent estimate: identify with "
                             "`oed identify --consistent`")
    raise ModelFileError(f"the model file holds no model {name!r}; it holds: {', '.join(alternative_names(model_file))}")


@dataclass(frozen=True)
class Prediction:
    """Predicted channels along a record, with their 95 % prediction band.

    Attributes
    ----------
    t
        ``(N,)`` time, s.
    predicted, lower, upper
        ``(N, m)`` prediction and its 95 % band.
    measured
        ``(N, m)`` the channels as recorded on those samples (``None`` when the record has none).
    channels
        Channel names.
    stamps
        ``(N,)`` the samples' time stamps as recorded when :attr:`t` is another time base (the regular clock of a
        model file whose preprocessing says ``time_base: regular``); ``None``: :attr:`t` is the stamps.
    """

    t: NDArray[np.float64]
    predicted: NDArray[np.float64]
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    measured: NDArray[np.float64] | None
    channels: tuple[str, ...]
    stamps: NDArray[np.float64] | None = None

    @property
    def mse(self) -> dict[str, float]:
        """Mean squared error per channel against the channels as recorded."""
        if self.measured is None:
            raise ValueError("the record holds no measured channels to compare with")
        return channel_mse(self.measured, self.predicted, self.channels)

    def columns(self) -> dict[str, NDArray[np.float64]]:
        """``t``, then per channel its prediction, ``_lo`` and ``_hi``, then (when the record holds the channels)
        per channel ``_measured`` (as recorded) and ``_residual`` (measured minus predicted): the CSV of
        ``oed predict``. ``t`` holds the stamps as recorded; on a regular clock (:attr:`stamps`) its instants
        come last, as ``t_clock`` (a reader of the other columns unchanged)."""
        table = {"t": self.t if self.stamps is None else self.stamps}
        for index, channel in enumerate(self.channels):
            table[channel] = self.predicted[:, index]
            table[f"{channel}_lo"] = self.lower[:, index]
            table[f"{channel}_hi"] = self.upper[:, index]
        if self.measured is not None:
            for index, channel in enumerate(self.channels):
                table[f"{channel}_measured"] = self.measured[:, index]
                table[f"{channel}_residual"] = self.measured[:, index] - self.predicted[:, index]
        if self.stamps is not None:
            table["t_clock"] = self.t
        return table

    def plot(self, path: str | Path | None = None, *, title: str = "", max_points: int = 4000) -> Figure:
        """Per channel, measured (as recorded) and predicted with its 95 % band, and below it the residual, against
        time (every k-th sample beyond ``max_points``); saved to ``path`` when given (format from the suffix)."""
        from matplotlib.figure import Figure  # no pyplot; here: a run without figures skips matplotlib

        step = max(1, -(-self.t.shape[0] // max_points))
        t = self.t[::step]
        figure = Figure(figsize=(11, 3.6 * len(self.channels)))
        axes = figure.subplots(2 * len(self.channels), 1, sharex=True, squeeze=False,
                               gridspec_kw={"height_ratios": (3, 2) * len(self.channels)})[:, 0]
        for index, channel in enumerate(self.channels):
            top, bottom = axes[2 * index], axes[2 * index + 1]
            top.fill_between(t, self.lower[::step, index], self.upper[::step, index], color="C3", alpha=0.2,
                             linewidth=0, label="95 % band")
            if self.measured is not None:
                top.plot(t, self.measured[::step, index], color="0.45", linewidth=0.8, label="measured")
                bottom.plot(t, (self.measured - self.predicted)[::step, index], color="C0", linewidth=0.7)
                top.text(0.99, 0.95, f"MSE {self.mse[channel]:.3g}", transform=top.transAxes, ha="right", va="top",
                         fontsize=8)
            top.plot(t, self.predicted[::step, index], color="C3", linewidth=0.9, label="predicted")
            top.set_ylabel(channel)
            bottom.set_ylabel(f"residual {channel}")
        axes[0].legend(loc="upper left", fontsize=8)
        axes[-1].set_xlabel("t [s]" + (f" (every {step}th of {self.t.shape[0]} samples)" if step > 1 else ""))
        if title:
            figure.suptitle(title)
        figure.tight_layout()
        if path is not None:
            save_figure(figure, path)
        return figure


@dataclass(frozen=True)
class Evaluation:
    """A model's prediction of new records, and the yardsticks beside it (the ``metrics.json`` of ``oed predict``)."""

    prediction: Prediction
    zero_mse: dict[str, float]
    nominal_mse: dict[str, float]
    floor_mse: dict[str, float] | None
    reported_validation_mse: dict[str, float] | None
    #: the name of the model that predicted (the chosen one's, or an alternative's)
    model: str | None = None
    #: the record against each joint's training range (:mod:`estimation.identification.training_range`); ``None``:
    #: the model file holds none (an earlier release's), the check cannot tell
    range_check: RangeCheck | None = None
    #: whether the load or the mount changed since the training, tested on this record
    #: (:mod:`estimation.identification.record_changes`); ``None``: not checked
    changes: RecordChanges | None = None

    @property
    def mse_over_floor(self) -> dict[str, float] | None:
        return mse_over_floor(self.prediction.mse, self.floor_mse)

    @property
    def channel_samples(self) -> dict[str, int] | None:
        """Each channel's valid samples, its error's, where they differ by channel (a channel's masked samples
        left out: :mod:`estimation.data.channel_mask`); ``None``: every channel's over ``n_samples``."""
        measured = self.prediction.measured
        if measured is None:
            return None
        counts = channel_counts(measured)
        if np.all(counts == measured.shape[0]):
            return None
        return {channel: int(count) for channel, count in zip(self.prediction.channels, counts)}

    def to_dict(self) -> dict[str, Any]:
        return {"mse": self.prediction.mse, "mse_over_floor": self.mse_over_floor,
                "n_samples": int(self.prediction.t.shape[0]), "channel_samples": self.channel_samples,
                "zero_mse": self.zero_mse, "nominal_mse": self.nominal_mse, "noise_floor_mse": self.floor_mse,
                "reported_validation_mse": self.reported_validation_mse, "model": self.model,
                "outside_training_range": None if self.range_check is None else self.range_check.to_dict(),
                "training_range_note": UNKNOWN_RANGE if self.range_check is None else None,
                "changed": None if self.changes is None else self.changes.to_dict()}


class IdentifiedModel:
    """An identified model rebuilt from its :class:`~estimation.identification.model_file.ModelFile`."""

    def __init__(self, model_file: ModelFile, *, estimate: str | None = None) -> None:
        if not isinstance(model_file, ModelFile):
            raise TypeError(f"model_file must be a ModelFile, got {type(model_file).__name__}")
        if estimate is not None and not isinstance(estimate, str):
            raise TypeError(f"estimate must be a name or None, got {type(estimate).__name__}")
        self.file = model_file
        self.estimate, entry = _selected(model_file, estimate)
        self.robot = model_file.robot.load()
        self.description_gravity = np.asarray(self.robot.gravity, dtype=float)  # the description's, as loaded
        self.description_robot = self.robot  # the description as given: the load a log subtracted is its
        if model_file.gravity is not None and not np.array_equal(model_file.gravity, self.robot.gravity):
            self.robot = self.robot.with_gravity(model_file.gravity)  # the gravity the model was fitted with
        if list(self.robot.joint_names) != list(model_file.joint_names):
            raise ModelFileError(f"the robot's joints {self.robot.joint_names} are not the model's "
                                 f"{list(model_file.joint_names)}")
        self.transmission = None if model_file.transmission is None else \
            transmission_from_json(model_file.transmission, self.robot)
        effects = tuple(self._smoothed(effect) for effect in build_effects(
            None if model_file.effects == "none" else model_file.effects, self.robot, self.transmission))
        self.model: IdentificationModel = build_model(self.robot, model_file.model, effects)
        if tuple(self.model.base.names) != tuple(model_file.names):
            raise ModelFileError("the model rebuilt from the file has other base parameters than it was identified "
                                 f"with ({list(self.model.base.names)[:5]}… against {list(model_file.names)[:5]}…)")
        if model_file.subtracted is not None and not load_channels(self.model):
            raise ModelFileError("the model file says the log subtracts a load from the joint torques, but its "
                                 f"channels {list(self.model.channels)} are not joint torques")
        self.theta = np.asarray(entry.theta, dtype=float)
        self.cov = np.asarray(entry.cov, dtype=float).reshape(self.theta.shape[0], -1)
        self.shape: dict[str, float] = dict(entry.shape)
        self.delay: float | None = entry.delay
        self.band_variance = entry.band_variance
        self._reported = entry.validation_mse
        self._blocks, self._replaced = shaped_blocks(self.model) if self._shaped else ([], [])
        missing = [parameter.name for block in self._blocks for parameter in block.parameters
                   if parameter.name not in self.shape]
        if missing:
            raise ModelFileError(f"the model file lacks the fitted shape parameters {missing}")
        self.payload_link: int | None = None  # 1-based index of the payload's link
        self.payload_theta = self.payload_cov = None
        if model_file.payload is not None:
            index = int(model_file.payload["link_index"])
            if not 1 <= index <= self.robot.n_joints:
                raise ModelFileError(f"the model file's payload is on link {index}; the robot has "
                                     f"{self.robot.n_joints}")
            self.payload_link = index
            self.payload_theta = np.asarray(model_file.payload["parameters"], dtype=float)
            self.payload_cov = np.asarray(model_file.payload["cov"], dtype=float)

    @classmethod
    def load(cls, path: str | Path, *, estimate: str | None = None) -> IdentifiedModel:
        """The model of a ``result.json`` (``oed identify``) or ``report.json`` (``oed diagnose``): the one the
        verb chose, or the alternative named ``estimate`` (``ols``, ``wls``, ``consistent``; ``unconstrained``:
        the unconstrained fit behind the choice; :func:`alternative_names` lists them)."""
        return cls(read_model_file(path), estimate=estimate)

    @property
    def fitted_gravity(self) -> str | None:
        """``"gravity (gx, gy, gz) m/s², not the description's"`` when the model was fitted with another gravity than
        its description's (the model file's ``gravity``: a mount found and chosen on the validation record), else
        ``None``."""
        if np.allclose(self.robot.gravity, self.description_gravity, rtol=0.0, atol=1e-9):
            return None
        return f"gravity ({', '.join(f'{value:.4g}' for value in self.robot.gravity)}) m/s², not the description's"

    @property
    def subtracted_words(self) -> str | None:
        """``"the log less the description's gravity torque …"`` when the model file says the logged torques lack a
        load of the description (``subtracted``: :meth:`predict` subtracts it), else ``None``."""
        if self.file.subtracted is None:
            return None
        return f"the log less {self.file.subtracted.words().removesuffix(' subtracted by the logger')}"

    @property
    def reported_validation_mse(self) -> dict[str, float] | None:
        """The validation MSE the identification reported for this estimate."""
        return None if self._reported is None else dict(self._reported)

    @property
    def _shaped(self) -> bool:
        return any(is_shaped(effect, self.robot) for effect in self.model.effects)

    @property
    def channels(self) -> tuple[str, ...]:
        return tuple(self.model.channels)

    @property
    def preprocessing(self) -> Preprocessing:
        return preprocessing_from_dict(None if self.file.preprocessing is None else dict(self.file.preprocessing))

    def _smoothed(self, effect: Any) -> Any:
        """``effect`` with the Coulomb smoothing it was identified with (``--rest smooth``)."""
        smoothing = self.file.smoothing.get(effect_spec(effect))
        if smoothing is None or "smoothing" not in {field.name for field in dataclasses.fields(effect)}:
            return effect
        return dataclasses.replace(effect, smoothing=float(smoothing))

    def regressor(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> NDArray[np.float64]:
        """The base regressor ``(N, m, r)`` with the shaped columns at the fitted shapes."""
        q, dq, ddq = check_states(self.robot.n_joints, q, dq, ddq)
        Y = np.array(self.model.evaluate_base(q, dq, ddq))
        states = States(q, dq, ddq)
        position = 0
        for block in self._blocks:
            shape = np.array([self.shape[parameter.name] for parameter in block.parameters])
            columns = block.evaluate(states, shape)
            indices = list(self._replaced[position:position + block.n_linear])
            position += block.n_linear
            Y[:, :, indices] = 0.0
            for row_position, row in enumerate(block.rows):
                Y[:, row, indices] = columns[:, row_position, :]
        return Y

    def link_columns(self, link: int, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> NDArray[np.float64]:
        """``(N, m, 10)``: the ten standard-parameter columns of link ``link`` (1-based) in the model's channels
        (the Newton–Euler regressor, :mod:`dynamics.newton_euler`): what a body fixed to that link adds per unit
        of its parameters."""
        if not 1 <= int(link) <= self.robot.n_joints:
            raise ValueError(f"link must be 1 to {self.robot.n_joints}, got {link}")
        start = 10 * (int(link) - 1)
        return np.ascontiguousarray(self.model.evaluate(q, dq, ddq)[:, :, start:start + 10])

    def robot_prediction(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> NDArray[np.float64]:
        """``(N, m)`` the robot model's prediction alone (without the payload the file may carry)."""
        if not self._shaped:
            return self.model.predict(self.theta, q, dq, ddq)
        return self.regressor(q, dq, ddq) @ self.theta

    def predict(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> NDArray[np.float64]:
        """``(N, m)`` predicted channels along the motion ``q, dq, ddq`` (``(N, n)`` each; no delay applied:
        :meth:`predict_record` moves a record's motion by it), the payload included when the file carries one, in
        the log's units: times each channel's gain on the recorded torque when the file holds ``torque_gains``
        (:mod:`estimation.consistent.torque_gains`), as the verb that wrote the file scored it."""
        predicted = self.robot_prediction(q, dq, ddq)
        if self.payload_link is not None:
            predicted = predicted + self.link_columns(self.payload_link, q, dq, ddq) @ self.payload_theta
        if self.file.subtracted is not None:  # what the log records: the model's torques less the load it lacks
            predicted = predicted - self.subtracted_load(q)
        if self.file.torque_gains is not None:  # the torques in the log's units: the model's times each gain
            predicted = predicted * self.file.channel_gains()
        return predicted

    def subtracted_load(self, q: ArrayLike) -> NDArray[np.float64]:
        """``(N, m)``: the load the logged torques lack on each channel at the positions ``q`` (the model file's
        ``subtracted``, :mod:`estimation.identification.subtracted_load`; zero without one)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if self.file.subtracted is None:
            return np.zeros((q.shape[0], len(self.channels)))
        return subtracted_torque(self.file.subtracted, self.description_robot, q)[:, list(load_channels(self.model))]

    def interval(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike, *, z: float = Z_95) -> NDArray[np.float64]:
        """``(N, m)`` half-widths ``z √(y_bᵀ Σ_θ y_b + σ_c²)`` of the prediction band (module docstring), in the
        log's units as :meth:`predict`."""
        Y = self.regressor(q, dq, ddq)
        variance = np.einsum("nmr,rs,nms->nm", Y, self.cov, Y, optimize=True)
        if self.payload_link is not None:
            Y = self.link_columns(self.payload_link, q, dq, ddq)
            variance += np.einsum("nmr,rs,nms->nm", Y, self.payload_cov, Y, optimize=True)
        if self.file.torque_gains is not None:  # the band in the log's units (the noise variance recorded in them)
            gains = self.file.channel_gains()
            band = self.band_variance if self.file.recorded_variance is not None else self.band_variance * gains**2
            return z * np.sqrt(np.clip(variance, 0.0, None) * gains[None, :] ** 2 + band[None, :])
        return z * np.sqrt(np.clip(variance, 0.0, None) + self.band_variance[None, :])

    def predict_record(self, measurements: Measurements) -> Prediction:
        """The prediction along a prepared record (``q, dq, ddq`` present), its motion moved by the fitted
        delay, paired with the channels as recorded (:attr:`Measurements.as_recorded`)."""
        if measurements.dq is None or measurements.ddq is None:
            raise ValueError("the record lacks dq/ddq: prepare it first (IdentifiedModel.prepare, or "
                             "estimation.preprocessing.plan.prepare)")
        if self.delay is not None:
            measurements = delayed(measurements, self.delay)
        record = measurements.as_recorded
        predicted = self.predict(record.q, record.dq, record.ddq)
        half = self.interval(record.q, record.dq, record.ddq)
        try:
            measured = record.channels(self.channels)
        except (KeyError, ValueError):
            measured = None
        directions = self.file.joint_directions
        if directions is not None and directions.reversed:  # the torques back in the log's directions (read flipped)
            signs = self.channel_signs()
            predicted = predicted * signs
            measured = None if measured is None else measured * signs
        return Prediction(record.t, predicted, predicted - half, predicted + half, measured, self.channels)

    def channel_signs(self) -> NDArray[np.float64]:
        """Each channel's sign in the log against the model's (``-1``: a joint whose torque the log records reversed,
        the model file's ``joint_directions``; ``1`` elsewhere)."""
        directions = self.file.joint_directions
        if directions is None or not directions.reversed:
            return np.ones(len(self.channels))
        return np.array([directions.torque_signs[torque_joint(channel)] if is_joint_torque(channel) else 1.0
                         for channel in self.channels])

    def read(self, paths: Sequence[str | Path]) -> tuple[Measurements, ...]:
        """The segments of the files, motor-side columns converted by the model's transmission, the model file's
        ``joint_offsets`` added to the joint positions."""
        return self.on_time_base(self.read_as_stamped(paths))

    def read_as_stamped(self, paths: Sequence[str | Path]) -> tuple[Measurements, ...]:
        """The segments of the files at their stamps, whatever the model file's time base (:meth:`read`)."""
        max_gap = DEFAULT_MAX_GAP if self.file.max_gap is None else float(self.file.max_gap)
        segments: list[Measurements] = []
        for path in paths:
            segments.extend(read_record_with_transmission(path, model=self.model, transmission=self.transmission,
                                                          max_gap=max_gap, split=True,
                                                          joint_offsets=self.file.joint_offsets,
                                                          joint_directions=self.file.joint_directions))
        return tuple(segments)

    def on_time_base(self, segments: Sequence[Measurements]) -> tuple[Measurements, ...]:
        """``segments`` on the model file's time base: as they are for ``stamps``; each resampled one on its regular
        clock for ``regular`` (:func:`estimation.data.sampling_clock.on_regular_clock`), one whose stamps give no
        regular clock kept at its stamps, said."""
        if self.preprocessing.time_base != "regular":
            return tuple(segments)
        moved = []
        for segment in segments:
            clocked = on_regular_clock(segment)
            if clocked is None:
                warnings.warn(f"{segment.metadata.get('source', 'the record')}: the model was identified with the "
                              "samples on a regular clock, but this record's stamps give none (a dropped row or a "
                              "stall inside a segment): its samples are taken at their stamps", stacklevel=3)
            moved.append(segment if clocked is None else clocked)
        return tuple(moved)

    def prepare(self, segments: Sequence[Measurements]) -> Measurements:
        """Derive the motion as the model's preprocessing says and drop the rows at rest as it did."""
        preprocessing = self.preprocessing
        if preprocessing.method == "fourier":
            check_frequency(segments, preprocessing.frequency_hz)
        prepared = prepare_unseen(segments, preprocessing, role="the data to predict",
                                  fallback=best_filter(self.file.preprocessing))
        rest = self.file.rest
        if rest is not None and rest.get("rest") == "drop" and rest.get("min_speed"):
            prepared = drop_rest(prepared, float(rest["min_speed"]), combinations=coulomb_combinations(self.model.effects),
                                 source="prediction").measurements
        return prepared

    def floor(self, segments: Sequence[Measurements]) -> dict[str, float] | None:
        """The noise floor per channel of the records as read (as ``oed diagnose`` measures it), or ``None``: on the
        samples as recorded (a resampled log's own, whose interpolation onto a grid would smooth the noise)."""
        preprocessing = self.preprocessing
        frequency = preprocessing.frequency_hz if preprocessing.method == "fourier" else None
        floors = []
        for segment in segments:
            try:
                floors.append(noise_floor(segment.as_recorded, self.channels, frequency_hz=frequency))
            except NoiseFloorError as error:
                warnings.warn(f"no noise floor from {segment.metadata.get('source', 'the record')}: {error}",
                              stacklevel=2)
        pooled = pooled_floor(floors)
        return None if pooled is None else dict(pooled.mse())

    def check_range(self, measurements: Measurements, *, record: str = "the record",
                    warn: bool = True) -> RangeCheck | None:
        """The prepared record ``measurements`` against each joint's training range the file holds
        (:mod:`estimation.identification.training_range`; ``None``: the file holds none, the check cannot tell);
        with ``warn``, an :class:`ExtrapolationWarning` naming each joint the record leaves it on, by how much and
        on what fraction of the samples."""
        ranges = self.file.training_range
        if ranges is None:
            return None
        check = ranges.check(measurements.q, measurements.dq)
        for message in check.messages(record) if warn else ():
            warnings.warn(message, ExtrapolationWarning, stacklevel=2)
        return check

    def evaluate(self, paths: Sequence[str | Path], *, changes: bool = True) -> Evaluation:
        """Read ``paths`` (the segments of one record), prepare them, predict and compare (``oed predict``); a
        record that leaves the joints' training range is said (:meth:`check_range`); ``changes``: the residual tested
        for a load or a mount changed since the training (:mod:`estimation.identification.record_changes`; the
        prediction unchanged)."""
        stamped = self.read_as_stamped(paths)
        segments = self.on_time_base(stamped)
        prepared = self.prepare(segments)
        # the yardsticks on the torques the model holds (the log with the load it lacks added back), as the verb that
        # took that model reported them
        trivial = trivial_mse(self.model, prepared if self.file.subtracted is None
                              else added_back(prepared, self.file.subtracted, self.description_robot))
        check = self.check_range(prepared)
        prediction = self.predict_record(prepared)
        if any(segment is not original for segment, original in zip(segments, stamped)):
            prediction = dataclasses.replace(prediction, stamps=recorded_stamps(prediction.t, segments, stamped))
        floor = self.floor(segments)
        found = check_record_changes(self, prepared, prediction, floor) if changes else None
        return Evaluation(prediction, trivial["zero_mse"], trivial["nominal_mse"], floor,
                          self.reported_validation_mse, self.estimate, check, found)
