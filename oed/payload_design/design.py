"""A short excitation for a payload's parameters, the robot's identified model given (``oed design --payload``).

:class:`PayloadDesign` is :class:`oed.design_problem.ExcitationDesign` (the Fourier trajectory of eq. 18, the bounds
of eq. 19, constraint refinement, IPOPT, multi-start) with the information of the payload's ten parameters in place
of the base parameters': over ``N`` cost samples of one period,

    M = (1/N) Σ_k Y_kᵀ W Y_k ,     W = diag(1/σ_c²),

``Y_k`` the ten standard-parameter columns of the payload's link in the model's channels (the Newton–Euler
regressor) and ``σ_c²`` the robot model's channel noise, under the criterion
:class:`oed.payload_design.criterion.MassAndCentre` (the worst relative standard deviation of the mass and the centre of
mass). One period is the experiment (``frequency_hz`` sets its length: by default 0.1 Hz, 10 s).

**What the default design counts** (issue 37): the criterion is the payload record's torque noise, the robot model
given: the part of the payload's uncertainty the payload experiment is there to shrink. The robot model's own share
(its parameters' covariance propagated through its prediction) cannot be shrunk by a payload experiment, but it
depends on the motion: it grows where the motion leaves what the robot's own records covered, and a design for the
record's noise alone can drive the motion there (measured on the 6-joint PUMA, benchmarks/bench_payload.py, its robot
model identified on a random record: the record's noise part of the mass's standard deviation 2.6–2.7x below random
excitations' median, its robot share 4x above, the total 2.2x worse). So by default (``robot_share="bounded"``) a constraint holds the robot model's share of the
variance of the mass and of each axis of the centre of mass at most the median over :data:`REFERENCE_EXCITATIONS`
random excitations of the same period and bounds (:class:`oed.payload_design.constraints.RobotShareBound`): the design
never leaves the robot model's share, and so the total, worse than a random excitation would. Measured on the PUMA
with its robot model identified on ``oed design``'s excitation (10–120 s), the bound costs nothing: the mass's
record-noise standard deviation 2.5–2.9x below random excitations', the centre of mass's 2.9–4.6x, the robot share
no larger, in total 1.3–2.2x and 1.6–3.9x better than random. With a robot model identified on a random record (of any
length: the bound is relative) it is the price: the mass's record noise 1.6–2.0x (benchmarks/README.md, with the
trade-off against ``allowance``, the ratio of standard deviations the share may exceed the reference by). ``"counted"``
(``--payload-robot-share``) puts the share in the criterion (the information of the stacked columns ``[Y_k | Y_b]``),
``"ignored"`` (``--payload-noise-only``) leaves it free.

The result reports the standard deviations of the mass and the centre of mass an experiment of one period would
give, by part (``record_noise``, ``robot_model``) and in total, for the design and for the median of the
:data:`REFERENCE_EXCITATIONS` random excitations (within the same bounds and period, drawn from the design's seed: its
starts are the first of them).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Any

import casadi
import numpy as np
from numpy.typing import NDArray

from dynamics.effects.shaped import is_shaped
from estimation.identification.identified_model import IdentifiedModel
from estimation.payload import resolve_link
from oed.bounds import JointBounds
from oed.criteria import LogDet
from oed.excitation import DesignResult, design_excitation
from oed.design_problem import ExcitationDesign, StartResult
from oed.design_settings import DesignSettings
from oed.design_solver import jit_options, stacked_information
from oed.fourier import FourierTrajectory
from oed.payload_design.constraints import RobotShareBound, reference_robot_share
from oed.payload_design.criterion import DEFAULT_LENGTH, DEFAULT_MASS, MassAndCentre

__all__ = ["PAYLOAD_FREQUENCY_HZ", "PAYLOAD_HARMONICS", "REFERENCE_EXCITATIONS", "PayloadDesign", "PayloadDesignResult",
           "RobotShare", "design_payload_excitation", "payload_regressor"]


#: one period of 10 s with harmonics up to 1 Hz: measured on the 6-joint PUMA (benchmarks/bench_payload.py), 10
#: harmonics gave the mass's standard deviation 2.7 times and the centre of mass's 4.6 times below random
#: excitations', 5 harmonics 1.3 and 3.7 times
PAYLOAD_FREQUENCY_HZ = 0.1
PAYLOAD_HARMONICS = 10
#: random excitations of the same period and bounds whose median is the robot model's share a ``bounded`` design
#: may not exceed, and the design's yardstick in its report
REFERENCE_EXCITATIONS = 12
#: a robot-share bound's row below ``-BOUND_TOLERANCE`` on the ``rate_hz`` grid is reported (1 % in variance)
BOUND_TOLERANCE = 0.01


class RobotShare(str, Enum):
    """What the payload design does with the robot model's share of the payload's uncertainty."""

    #: at most that of random excitations of the same period and bounds (their median), a constraint
    BOUNDED = "bounded"
    #: in the criterion, with the record's noise (the total)
    COUNTED = "counted"
    #: reported only
    IGNORED = "ignored"


def robot_share_available(model: IdentifiedModel) -> bool:
    """Whether the robot model's prediction is linear in its parameters (no shaped laws): its base regressor is then
    symbolic and the design counts the robot model's share of the payload's uncertainty."""
    return not any(is_shaped(effect, model.robot) for effect in model.model.effects)


def payload_regressor(model: IdentifiedModel, link: int, *, with_robot: bool = False) -> casadi.Function:
    """``payload_regressor(q, dq, ddq) -> Y``: the link's ten columns (then, ``with_robot``, the robot model's base
    regressor ``Y_b``), each channel's row divided by its noise ``σ_c``."""
    return _payload_regressor(model, int(link), bool(with_robot))


@functools.lru_cache(maxsize=8)
def _payload_regressor(model: IdentifiedModel, link: int, with_robot: bool) -> casadi.Function:
    n = model.robot.n_joints
    q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
    columns = model.model.regressor(q, dq, ddq)[:, 10 * (link - 1):10 * link]
    if with_robot:
        columns = casadi.horzcat(columns, model.model.base_regressor(q, dq, ddq))
    sigma = np.sqrt(np.maximum(np.asarray(model.file.band_variance, dtype=float), np.finfo(float).tiny))
    weighted = casadi.mtimes(casadi.diag(casadi.DM(1.0 / sigma)), columns)
    return casadi.Function("payload_regressor", [q, dq, ddq], [casadi.cse(weighted)], ["q", "dq", "ddq"], ["Y"])


@dataclass(frozen=True, eq=False)
class PayloadDesign(ExcitationDesign):
    """The payload's excitation design (module docstring); ``criterion`` a :class:`MassAndCentre`.

    Parameters
    ----------
    regressor
        :func:`payload_regressor` of the robot's model and the payload's link.
    """

    regressor: casadi.Function | None = None
    information_constraints: tuple = ()
    _payload_cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.regressor, casadi.Function):
            raise TypeError("regressor must be the casadi Function of oed.payload_design.design.payload_regressor")
        if not isinstance(self.criterion, MassAndCentre):
            raise TypeError("criterion must be a MassAndCentre")
        constraints = tuple(self.information_constraints)
        width = self.regressor.size2_out(0)
        for constraint in constraints:
            if not (callable(getattr(constraint, "expression", None)) and callable(getattr(constraint, "margins", None))):
                raise TypeError("information_constraints must have expression() and margins() "
                                f"(oed.payload_design.constraints), got {type(constraint).__name__}")
            if constraint.size != width:
                raise ValueError(f"the {constraint.name} constraint takes the information of {constraint.size} columns, "
                                 f"the regressor gives {width} (payload_regressor(..., with_robot=True))")
        if self.criterion.size != width and not (self.criterion.robot_cov is None and constraints):
            raise ValueError(f"the criterion takes the information of {self.criterion.size} columns, the regressor "
                             f"gives {width}")
        object.__setattr__(self, "information_constraints", constraints)

    def sampled_information(self, x: casadi.MX) -> casadi.MX:
        """``M`` per sample over the ``cost_samples`` instants, as an expression of ``x``: ``10 x 10`` for the ten
        payload columns; with the robot's columns (``p = 10 + r``) only the ``p x 10`` block the criterion and the
        constraints use, ``Σ_k Y_kᵀ Y_k[:, :10]``, one product of the stacked per-sample transposes."""
        N = self.settings.cost_samples
        states = self.sampled_states(x)  # (n, N) each: q, dq, ddq
        if self.regressor.size2_out(0) == 10:
            return stacked_information(self.regressor, states, self.settings.jit) / N
        n = self.n_joints
        q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
        transposed = casadi.Function("payload_regressor_t", [q, dq, ddq], [self.regressor(q, dq, ddq).T],
                                     ["q", "dq", "ddq"], ["Yt"], jit_options() if self.settings.jit else {})
        stacked = transposed.map(N, "serial")(*states)  # (p, rows N)
        return casadi.mtimes(stacked, stacked[:10, :].T) / N

    def cost_function(self) -> casadi.Function:
        """``payload_objective(x) -> J``: the criterion of ``M`` over ``cost_samples`` samples (cached)."""
        if "cost" not in self._cache:
            x = casadi.MX.sym("x", self.n_variables)
            information = self.sampled_information(x)
            self._cache["cost"] = casadi.Function("payload_objective", [x], [self.criterion.expression(information)],
                                                  ["x"], ["J"])
        return self._cache["cost"]

    def information_rows(self) -> casadi.Function | None:
        """``x -> g``: the information constraints' rows over the ``cost_samples`` instants (``g ≥ 0`` met;
        ``None`` without them; cached)."""
        if not self.information_constraints:
            return None
        if "information_rows" not in self._cache:
            x = casadi.MX.sym("x", self.n_variables)
            information = self.sampled_information(x)
            g = casadi.vertcat(*(constraint.expression(information) for constraint in self.information_constraints))
            self._cache["information_rows"] = casadi.Function("payload_information_constraints", [x], [g], ["x"], ["g"])
        return self._cache["information_rows"]

    def nonlinear_function(self, indices: NDArray[np.int64]) -> casadi.Function | None:
        """The per-sample constraints' rows at ``indices`` (:meth:`ExcitationDesign.nonlinear_function`), then the
        information constraints' (which do not depend on the points)."""
        pointwise, whole = super().nonlinear_function(indices), self.information_rows()
        if whole is None or pointwise is None:
            return whole if pointwise is None else pointwise
        x = casadi.MX.sym("x", self.n_variables)
        return casadi.Function("design_constraints", [x], [casadi.vertcat(pointwise(x), whole(x))], ["x"], ["g"])

    def _extend_multipliers(self, lam_g: NDArray, old: tuple[int, ...], new: tuple[int, ...]) -> NDArray:
        """As :meth:`ExcitationDesign._extend_multipliers`, the information constraints' multipliers (the last rows)
        kept as they are."""
        whole = self.information_rows()
        if whole is None:
            return super()._extend_multipliers(lam_g, old, new)
        rows = whole.size1_out(0)
        return np.concatenate([super()._extend_multipliers(lam_g[:-rows], old, new), lam_g[-rows:]])

    def cost_grid_information(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """``M`` per sample of ``x`` on the ``cost_samples`` instants (what the optimiser sees), as numbers."""
        s = self.settings
        t = np.arange(s.cost_samples) / s.cost_samples / s.frequency_hz
        block = np.asarray(x, dtype=float).reshape(self.n_joints, -1)
        q, dq, ddq = (block @ matrix for matrix in self._state_matrices(t))
        return self.information(q.T, dq.T, ddq.T) / s.cost_samples

    def information_margins(self, x: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Each information constraint's rows at ``x`` on the ``rate_hz`` grid (``≥ 0``: met), by name."""
        if not self.information_constraints:
            return {}
        q, dq, ddq = self.sample(x)[1:]
        M = self.information(q, dq, ddq) / q.shape[0]
        return {constraint.name: constraint.margins(M) for constraint in self.information_constraints}

    def information(self, q, dq, ddq) -> NDArray[np.float64]:
        """``Σ_k Y_kᵀ W Y_k`` at the given samples (the information one record of them holds; with the robot's
        columns, on ``(π, θ_b)``)."""
        key = "mapped", np.shape(q)[0]
        if key not in self._payload_cache:
            mapped = self.regressor.map(np.shape(q)[0])
            self._payload_cache[key] = mapped, nonzero_positions(mapped)
        mapped, positions = self._payload_cache[key]
        stacked = evaluated(mapped, q, dq, ddq, positions=positions)
        width = self.regressor.size2_out(0)
        Y = stacked.reshape(stacked.shape[0], -1, width).transpose(1, 0, 2).reshape(-1, width)  # [Y_1, Y_2, …]
        return Y.T @ Y

    def evaluate(self, x: NDArray[np.float64], samples: tuple[NDArray[np.float64], ...] | None = None
                 ) -> dict[str, float]:
        """``cost`` (−log det of the per-sample information), its ``cond`` and the criterion, over one period."""
        q, dq, ddq = self.sample(x)[1:] if samples is None else samples
        M = self.information(q, dq, ddq) / q.shape[0]
        eigenvalues = np.linalg.eigvalsh((M + M.T) / 2)
        cond = float(np.sqrt(eigenvalues[-1] / eigenvalues[0])) if eigenvalues[0] > 0 else float("inf")
        return {"cost": LogDet().value(M), "cond": cond, "criterion": self.criterion.value(M)}

    def predicted_std(self, x: NDArray[np.float64]) -> dict[str, Any]:
        """Standard deviations of the mass (kg) and the centre of mass (m) a record of one period of ``x`` at
        ``rate_hz`` gives, at the criterion's guess: in total, from the record's noise and from the robot model."""
        q, dq, ddq = self.sample(x)[1:]
        noise, robot = self.criterion.relative_variances(self.information(q, dq, ddq) / q.shape[0])

        def described(variances):
            std = np.sqrt(np.clip(variances, 0.0, None))
            return {"mass": float(std[0] * self.criterion.mass),
                    "com": [float(value * self.criterion.length) for value in std[1:]]}

        return {**described(noise + robot), "record_noise": described(noise),
                "robot_model": described(robot) if self.criterion.robot_cov is not None else None}


def nonzero_positions(mapped: casadi.Function) -> NDArray[np.int64]:
    """Where the structural nonzeros of ``mapped``'s output sit in its dense column-major array (read-only).

    ``Sparsity.find`` builds a Python list of every nonzero's position (about 0.1 s for the 6-joint PUMA's
    regressor with its robot columns over one 500 Hz period): a property of the function, so found once per
    mapped function and handed to :func:`evaluated`.
    """
    positions = np.asarray(mapped.sparsity_out(0).find(), dtype=np.int64)
    positions.flags.writeable = False
    return positions


def evaluated(mapped: casadi.Function, *samples: NDArray[np.float64],
              positions: NDArray[np.int64] | None = None) -> NDArray[np.float64]:
    """The output of ``mapped`` (a per-sample function mapped over ``N`` samples) at ``samples`` (each ``(N, n)``),
    as a dense array: the value ``np.asarray(mapped(q.T, dq.T, ddq.T))`` gives, without the conversion of a casadi
    ``DM`` element by element (a Python list of every element: about 1 s for the 6-joint PUMA's regressor with
    its robot columns over one 500 Hz period, against 0.03 s written straight into the array here).
    ``positions``: :func:`nonzero_positions` of ``mapped`` when already found (found here otherwise)."""
    # (N, n) in C order is the (n, N) input in CasADi's column-major order
    inputs = [np.ascontiguousarray(values, dtype=float) for values in samples]
    sparsity = mapped.sparsity_out(0)
    buffer, trigger = mapped.buffer()
    for index, values in enumerate(inputs):
        buffer.set_arg(index, memoryview(values))
    nonzeros = np.empty(sparsity.nnz())
    buffer.set_res(0, memoryview(nonzeros))
    trigger()
    dense = np.zeros(sparsity.numel())  # column-major
    dense[nonzero_positions(mapped) if positions is None else positions] = nonzeros
    return dense.reshape(sparsity.size2(), sparsity.size1()).T


@dataclass(frozen=True)
class PayloadDesignResult:
    """The designed payload excitation and what it promises.

    Attributes
    ----------
    design
        The multi-start result (:class:`oed.excitation.DesignResult`); its trajectory is one period.
    link, link_index
        The payload's link.
    criterion
        The criterion the design minimised, with its guess of the payload (``criterion.robot_cov`` set: it counted
        the robot model's share too).
    designed_std, random_std
        Mass (kg) and centre-of-mass (m) standard deviations, in total and by part (``record_noise``,
        ``robot_model``; the latter ``None`` when the robot model's prediction is not linear in its parameters): of
        the design, and the median over ``references`` random excitations within the same bounds and period (the
        first of them the design's starts).
    robot_share
        What the design did with the robot model's share (:class:`RobotShare`; ``ignored`` when it could not be
        computed).
    constraints, margins
        The information constraints the design met (:class:`RobotShareBound` when ``bounded``) and their rows at
        the design on the ``rate_hz`` grid, by name (``≥ 0``: met).
    references, allowance
        The random excitations the reference and ``random_std`` are the median of; the ratio of standard deviations
        the robot model's share was allowed over the reference's.
    """

    design: DesignResult
    link: str
    link_index: int
    criterion: MassAndCentre
    designed_std: dict[str, Any]
    random_std: dict[str, Any]
    robot_share: RobotShare = RobotShare.IGNORED
    constraints: tuple = ()
    margins: dict[str, list[float]] = field(default_factory=dict)
    references: int = 0
    allowance: float = 1.0

    @property
    def trajectory(self) -> FourierTrajectory:
        return self.design.trajectory

    def to_dict(self) -> dict[str, Any]:
        """The trajectory's document (``oed design``) with ``payload_design``: the link, the guess and the predicted
        standard deviations."""
        document = self.trajectory.to_dict()
        document["payload_design"] = {
            "link": self.link, "link_index": self.link_index,
            "duration_s": 1.0 / self.trajectory.frequency_hz,
            "criterion": {"name": self.criterion.name, "mass": self.criterion.mass, "com": list(self.criterion.com),
                          "length": self.criterion.length, "value": self.design.criterion_value,
                          "robot_share": self.robot_share.value,
                          "counts": "record_noise" if self.criterion.robot_cov is None
                          else "record_noise+robot_model"},
            "robot_share_bound": None if not self.constraints else {
                **self.constraints[0].describe(), "allowance": self.allowance, "references": self.references,
                "margins": self.margins.get(self.constraints[0].name)},
            "predicted_std": {"designed": self.designed_std, "random_median": self.random_std,
                              "random_excitations": self.references,
                              "note": "one record of one period at the design's rate: by part, the record's torque "
                                      "noise (what a payload experiment shrinks) and the robot model's own "
                                      "uncertainty propagated (reported apart; null when its prediction is not "
                                      "linear in its parameters), and in total"},
            "warnings": list(self.warnings),
        }
        return document

    @property
    def warnings(self) -> tuple[str, ...]:
        """A warning for each of the mass and the centre of mass (worst axis) the design knows worse *in total* than
        the random excitations' median (the robot model's share grew on its motion past what the record's noise
        gained), and for a robot-share bound not met on the ``rate_hz`` grid (met on the optimiser's samples)."""
        designed, random = self.designed_std, self.random_std
        if self.robot_share is RobotShare.COUNTED or designed["robot_model"] is None:
            return ()
        found = []
        for label, unit, scale, ours, theirs in (
                ("mass", "g", 1e3, designed["mass"], random["mass"]),
                ("centre of mass", "mm", 1e3, max(designed["com"]), max(random["com"]))):
            if ours > theirs:
                found.append(f"in total (the robot model's share included) the design's {label} std {scale * ours:.3g} "
                             f"{unit} exceeds random excitations' {scale * theirs:.3g} {unit}: its motion goes where "
                             "the robot model is less known; "
                             + ("the default design bounds that share by random excitations', "
                                if self.robot_share is RobotShare.IGNORED else "")
                             + "--payload-robot-share counts it in the criterion, and a longer robot record lowers it")
        for constraint in self.constraints:
            margins = np.asarray(self.margins.get(constraint.name, []), dtype=float)
            if margins.size and margins.min() < -BOUND_TOLERANCE:
                worst = int(np.argmin(margins))
                found.append(f"the robot model's share of the {constraint.labels[worst]} std is "
                             f"{np.exp(-margins[worst] / 2):.3g} times its bound at the design's rate (met on the "
                             "optimiser's samples: more --samples)")
        return tuple(found)

    def table(self, rate_hz: float = 1000.0) -> tuple[list[str], NDArray[np.float64]]:
        """Columns ``t, q1..qn, dq1..dqn, ddq1..ddqn`` and the samples of one period at ``rate_hz`` (``--csv``)."""
        t, q, dq, ddq = self.trajectory.sample(rate_hz)
        n = self.trajectory.n_joints
        header = ["t"] + [f"{state}{i}" for state in ("q", "dq", "ddq") for i in range(1, n + 1)]
        return header, np.column_stack([t, q, dq, ddq])

    def summary(self) -> str:
        designed, random = self.designed_std, self.random_std
        noise, random_noise = designed["record_noise"], random["record_noise"]
        text = (f"payload excitation for link {self.link_index} ({self.link}), one period of "
                f"{1.0 / self.trajectory.frequency_hz:g} s, criterion on "
                + {RobotShare.COUNTED: "the record's noise and the robot model's share",
                   RobotShare.BOUNDED: "the record's noise, the robot model's share at most random excitations'"
                   + ("" if self.allowance == 1 else f" x {self.allowance:g}"),
                   RobotShare.IGNORED: "the record's noise"}[self.robot_share]
                + f"; predicted std (median of {self.references} random excitations in brackets): "
                f"from the record's noise: mass {noise['mass']:.3g} kg ({random_noise['mass']:.3g}), centre of mass "
                f"up to {1e3 * max(noise['com']):.3g} mm ({1e3 * max(random_noise['com']):.3g})")
        if designed["robot_model"] is None:
            return text + "; the robot model's share not computed (its prediction is not linear in its parameters)"
        robot, random_robot = designed["robot_model"], random["robot_model"]
        return (text + f"; the robot model's share, apart: mass {robot['mass']:.3g} kg ({random_robot['mass']:.3g}), "
                f"centre of mass up to {1e3 * max(robot['com']):.3g} mm ({1e3 * max(random_robot['com']):.3g}); in "
                f"total: mass {designed['mass']:.3g} kg ({random['mass']:.3g}), centre of mass up to "
                f"{1e3 * max(designed['com']):.3g} mm ({1e3 * max(random['com']):.3g})")


def design_payload_excitation(model: IdentifiedModel, *, bounds: JointBounds, link: str | int | None = None,
                              mass: float = DEFAULT_MASS, com: tuple[float, float, float] = (0.0, 0.0, 0.0),
                              length: float = DEFAULT_LENGTH, robot_share: RobotShare | str = "bounded",
                              settings: DesignSettings | None = None, starts: int = 4, seed: int | None = 0,
                              references: int = REFERENCE_EXCITATIONS, allowance: float = 1.0,
                              progress: Callable[[StartResult, int], None] | None = None) -> PayloadDesignResult:
    """Design the payload excitation (module docstring) for ``model`` (the robot's identified model).

    ``mass``, ``com``, ``length``: the guess of :class:`MassAndCentre`. The criterion counts the payload record's
    torque noise; ``robot_share`` says what becomes of the robot model's share of the uncertainty (its parameters'
    covariance, when its prediction is linear in them): ``"bounded"`` (default) at most that of random excitations
    (:class:`RobotShareBound`, the median over ``references`` random excitations of the same period and bounds, the
    first ``starts`` of them the design's starts), ``"counted"`` in the criterion too, ``"ignored"``. Either way both
    parts are reported, apart, for the design and for the median of the ``references`` random excitations.

    ``settings`` default to one period of :data:`PAYLOAD_FREQUENCY_HZ` (10 s) with :data:`PAYLOAD_HARMONICS`
    harmonics; ``criterion`` to a 1 kg payload at the link frame's origin, the centre of mass relative to 0.1 m.
    """
    if not isinstance(model, IdentifiedModel):
        raise TypeError(f"model must be an IdentifiedModel, got {type(model).__name__}")
    try:
        mode = RobotShare(robot_share)
    except ValueError:
        raise ValueError(f"robot_share must be one of {[choice.value for choice in RobotShare]}, "
                         f"got {robot_share!r}") from None
    if not (isinstance(allowance, (int, float, np.floating)) and np.isfinite(allowance) and allowance > 0):
        raise ValueError(f"allowance must be a positive number (a ratio of standard deviations), got {allowance!r}")
    if isinstance(references, bool) or not isinstance(references, (int, np.integer)) or references < 1:
        raise ValueError(f"references must be a positive integer, got {references!r}")
    index, name = resolve_link(model, link)
    settings = DesignSettings(frequency_hz=PAYLOAD_FREQUENCY_HZ, harmonics=PAYLOAD_HARMONICS) if settings is None \
        else settings
    available = robot_share_available(model)
    criterion = MassAndCentre(mass, com, length, samples=settings.period_samples)
    with_robot = replace(criterion, robot_cov=model.cov) if available else criterion
    # the report: both parts, the robot model's share whether the design counts it or not
    report = PayloadDesign(model.robot, model.file.model, bounds, with_robot, (), settings,
                           regressor=payload_regressor(model, index, with_robot=available))
    generator = np.random.default_rng(seed)  # the design draws its starts from the same: the first `starts` of these
    randoms = [report.random_start(generator) for _ in range(max(int(references), starts))]
    constraints: tuple = ()
    if available and mode is RobotShare.BOUNDED:
        reference = reference_robot_share(with_robot, (report.cost_grid_information(x) for x in randoms))
        constraints = (RobotShareBound(with_robot, allowance ** 2 * reference),)
    counted = available and mode is RobotShare.COUNTED
    problem = PayloadDesign(model.robot, model.file.model, bounds, with_robot if counted else criterion, (), settings,
                            regressor=payload_regressor(model, index, with_robot=counted or bool(constraints)),
                            information_constraints=constraints)
    result = design_excitation(model.robot, problem=problem, starts=starts, seed=seed, progress=progress)
    random_std = [report.predicted_std(x) for x in randoms]

    def median(entries):
        if any(entry is None for entry in entries):
            return None
        return {"mass": float(np.median([entry["mass"] for entry in entries])),
                "com": np.median([entry["com"] for entry in entries], axis=0).tolist()}

    random = {**median(random_std), **{part: median([entry[part] for entry in random_std])
                                       for part in ("record_noise", "robot_model")}}
    x = result.trajectory.to_vector()
    return PayloadDesignResult(result, name, index, problem.criterion, report.predicted_std(x), random,
                               mode if available else RobotShare.IGNORED, constraints,
                               {key: value.tolist() for key, value in problem.information_margins(x).items()},
                               len(randoms), float(allowance))
