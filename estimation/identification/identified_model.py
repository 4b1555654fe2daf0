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
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.effects.shaped import is_shaped
from dynamics.effects.specs import build_effects, effect_spec
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, build_model, check_states
from dynamics.runtime.output_files import save_figure
from dynamics.transmission_files import transmission_from_json
from estimation.data.log_cleaning import DEFAULT_MAX_GAP
from estimation.data.motor_side import read_record_with_transmission
from estimation.data.rest import coulomb_combinations, drop_rest
from estimation.estimators.effect_blocks import States
from estimation.identification.model_file import ModelFile, ModelFileError, read_model_file
from estimation.identification.shaped import shaped_blocks

if TYPE_CHECKING:
    from matplotlib.figure import Figure
from estimation.identification.trivial_predictors import trivial_mse
from estimation.identification.validation import channel_mse
from estimation.preprocessing.delay import delayed
from estimation.preprocessing.plan import Preprocessing, check_frequency, prepare
from estimation.uncertainty.noise_floor import NoiseFloorError, noise_floor, pooled_floor

__all__ = ["Z_95", "Evaluation", "IdentifiedModel", "Prediction", "preprocessing_from_dict"]

Estimate = Literal["unconstrained", "consistent"]
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
    return Preprocessing(**fields)


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
    """

    t: NDArray[np.float64]
    predicted: NDArray[np.float64]
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    measured: NDArray[np.float64] | None
    channels: tuple[str, ...]

    @property
    def mse(self) -> dict[str, float]:
        """Mean squared error per channel against the channels as recorded."""
        if self.measured is None:
            raise ValueError("the record holds no measured channels to compare with")
        return channel_mse(self.measured, self.predicted, self.channels)

    def columns(self) -> dict[str, NDArray[np.float64]]:
        """``t``, then per channel its prediction, ``_lo`` and ``_hi``, then (when the record holds the channels)
        per channel ``_measured`` (as recorded) and ``_residual`` (measured minus predicted): the CSV of
        ``oed predict``."""
        table = {"t": self.t}
        for index, channel in enumerate(self.channels):
            table[channel] = self.predicted[:, index]
            table[f"{channel}_lo"] = self.lower[:, index]
            table[f"{channel}_hi"] = self.upper[:, index]
        if self.measured is not None:
            for index, channel in enumerate(self.channels):
                table[f"{channel}_measured"] = self.measured[:, index]
                table[f"{channel}_residual"] = self.measured[:, index] - self.predicted[:, index]
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

    @property
    def mse_over_floor(self) -> dict[str, float] | None:
        if self.floor_mse is None:
            return None
        return {channel: value / self.floor_mse[channel] if self.floor_mse[channel] > 0 else float("inf")
                for channel, value in self.prediction.mse.items()}

    def to_dict(self) -> dict[str, Any]:
        return {"mse": self.prediction.mse, "mse_over_floor": self.mse_over_floor,
                "n_samples": int(self.prediction.t.shape[0]), "zero_mse": self.zero_mse,
                "nominal_mse": self.nominal_mse, "noise_floor_mse": self.floor_mse,
                "reported_validation_mse": self.reported_validation_mse}


class IdentifiedModel:
    """An identified model rebuilt from its :class:`~estimation.identification.model_file.ModelFile`."""

    def __init__(self, model_file: ModelFile, *, estimate: Estimate = "unconstrained") -> None:
        if not isinstance(model_file, ModelFile):
            raise TypeError(f"model_file must be a ModelFile, got {type(model_file).__name__}")
        if estimate not in ("unconstrained", "consistent"):
            raise ValueError(f"estimate must be 'unconstrained' or 'consistent', got {estimate!r}")
        if estimate == "consistent" and model_file.consistent_theta is None:
            raise ModelFileError("the model file holds no physically consistent estimate: identify with "
                                 "`oed identify --consistent`")
        self.estimate = estimate
        self.file = model_file
        self.robot = model_file.robot.load()
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
        consistent = estimate == "consistent"
        self.theta = np.asarray(model_file.consistent_theta if consistent else model_file.theta, dtype=float)
        self.cov = np.asarray(model_file.consistent_cov if consistent else model_file.cov, dtype=float)
        self._blocks, self._replaced = shaped_blocks(self.model) if self._shaped else ([], [])
        missing = [parameter.name for block in self._blocks for parameter in block.parameters
                   if parameter.name not in model_file.shape]
        if missing:
            raise ModelFileError(f"the model file lacks the fitted shape parameters {missing}")

    @classmethod
    def load(cls, path: str | Path, *, estimate: Estimate = "unconstrained") -> IdentifiedModel:
        """The model of a ``result.json`` (``oed identify``) or ``report.json`` (``oed diagnose``);
        ``estimate="consistent"``: its physically consistent estimate (``oed identify --consistent``)."""
        return cls(read_model_file(path), estimate=estimate)

    @property
    def reported_validation_mse(self) -> dict[str, float] | None:
        """The validation MSE the identification reported for this estimate."""
        reported = self.file.consistent_validation_mse if self.estimate == "consistent" \
            else self.file.reported_validation_mse
        return None if reported is None else dict(reported)

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
            shape = np.array([self.file.shape[parameter.name] for parameter in block.parameters])
            columns = block.evaluate(states, shape)
            indices = list(self._replaced[position:position + block.n_linear])
            position += block.n_linear
            Y[:, :, indices] = 0.0
            for row_position, row in enumerate(block.rows):
                Y[:, row, indices] = columns[:, row_position, :]
        return Y

    def predict(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> NDArray[np.float64]:
        """``(N, m)`` predicted channels along the motion ``q, dq, ddq`` (``(N, n)`` each; no delay applied:
        :meth:`predict_record` moves a record's motion by it)."""
        if not self._shaped:
            return self.model.predict(self.theta, q, dq, ddq)
        return self.regressor(q, dq, ddq) @ self.theta

    def interval(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike, *, z: float = Z_95) -> NDArray[np.float64]:
        """``(N, m)`` half-widths ``z √(y_bᵀ Σ_θ y_b + σ_c²)`` of the prediction band (module docstring)."""
        Y = self.regressor(q, dq, ddq)
        variance = np.einsum("nmr,rs,nms->nm", Y, self.cov, Y, optimize=True)
        return z * np.sqrt(np.clip(variance, 0.0, None) + self.file.band_variance[None, :])

    def predict_record(self, measurements: Measurements) -> Prediction:
        """The prediction along a prepared record (``q, dq, ddq`` present), its motion moved by the fitted
        delay, paired with the channels as recorded (:attr:`Measurements.as_recorded`)."""
        if measurements.dq is None or measurements.ddq is None:
            raise ValueError("the record lacks dq/ddq: prepare it first (IdentifiedModel.prepare, or "
                             "estimation.preprocessing.plan.prepare)")
        if self.file.delay is not None:
            measurements = delayed(measurements, self.file.delay)
        record = measurements.as_recorded
        predicted = self.predict(record.q, record.dq, record.ddq)
        half = self.interval(record.q, record.dq, record.ddq)
        try:
            measured = record.channels(self.channels)
        except (KeyError, ValueError):
            measured = None
        return Prediction(record.t, predicted, predicted - half, predicted + half, measured, self.channels)

    def read(self, paths: Sequence[str | Path]) -> tuple[Measurements, ...]:
        """The segments of the files, motor-side columns converted by the model's transmission."""
        max_gap = DEFAULT_MAX_GAP if self.file.max_gap is None else float(self.file.max_gap)
        segments: list[Measurements] = []
        for path in paths:
            segments.extend(read_record_with_transmission(path, model=self.model, transmission=self.transmission,
                                                          max_gap=max_gap, split=True))
        return tuple(segments)

    def prepare(self, segments: Sequence[Measurements]) -> Measurements:
        """Derive the motion as the model's preprocessing says and drop the rows at rest as it did."""
        preprocessing = self.preprocessing
        if preprocessing.method == "fourier":
            check_frequency(segments, preprocessing.frequency_hz)
        prepared = prepare(segments, preprocessing, role="the data to predict")
        rest = self.file.rest
        if rest is not None and rest.get("rest") == "drop" and rest.get("min_speed"):
            prepared = drop_rest(prepared, float(rest["min_speed"]), combinations=coulomb_combinations(self.model.effects),
                                 source="prediction").measurements
        return prepared

    def floor(self, segments: Sequence[Measurements]) -> dict[str, float] | None:
        """The noise floor per channel of the records as read (as ``oed diagnose`` measures it), or ``None``."""
        preprocessing = self.preprocessing
        frequency = preprocessing.frequency_hz if preprocessing.method == "fourier" else None
        floors = []
        for segment in segments:
            try:
                floors.append(noise_floor(segment, self.channels, frequency_hz=frequency))
            except NoiseFloorError as error:
                warnings.warn(f"no noise floor from {segment.metadata.get('source', 'the record')}: {error}",
                              stacklevel=2)
        pooled = pooled_floor(floors)
        return None if pooled is None else dict(pooled.mse())

    def evaluate(self, paths: Sequence[str | Path]) -> Evaluation:
        """Read ``paths`` (the segments of one record), prepare them, predict and compare (``oed predict``)."""
        segments = self.read(paths)
        prepared = self.prepare(segments)
        trivial = trivial_mse(self.model, prepared)
        return Evaluation(self.predict_record(prepared), trivial["zero_mse"], trivial["nominal_mse"],
                          self.floor(segments),
                          self.reported_validation_mse)
