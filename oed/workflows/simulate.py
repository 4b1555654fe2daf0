"""``oed simulate`` as a library call: simulated measurements of a robot tracking an excitation trajectory.

:func:`simulate` returns a :class:`SimulateRun`: ``write(out, truth=...)`` writes the data in the format of
:mod:`dynamics.measurements` (``t, q1..qn, [dq, ddq,] tau1..taun, fx fy fz mx my mz``: quantised positions, noisy
applied torques and base wrench) and, with ``truth``, the JSON record of the true parameters, effects, noise and
seed (``to_dict()``, its ``data`` key the file written).
"""

from __future__ import annotations

import copy
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dynamics.models import build_model
from dynamics.runtime.output_files import OutputFiles, json_text
from dynamics.simulation.controllers import ComputedTorqueController, computed_torque_gains
from oed.rest_ramps import playable
from dynamics.simulation.effects import Viscous, effects_from_friction, effects_from_names, is_friction_document
from dynamics.simulation.simulator import NoiseModel, Simulator
from oed.fourier import FourierTrajectory
from oed.workflows.options import RobotOptions, check_choice, optional_path, robot_of

__all__ = ["CONTROLLERS", "DATA_SUFFIXES", "SimulateOptions", "SimulateRun", "simulate"]

CONTROLLERS = ("pd", "computed-torque")
DATA_SUFFIXES = (".csv", ".parquet")


@dataclass(frozen=True, kw_only=True)
class SimulateOptions(RobotOptions):
    """The options of ``oed simulate`` by their names (``--noise-tau`` -> ``noise_tau``)."""

    trajectory: Path | None = None
    effects: str = ""
    effect_values: str | None = None
    controller: str = "pd"
    bandwidth: float = 4.0
    noise_tau: float = 0.2
    noise_wrench: tuple[float, ...] = (0.5, 0.5, 0.5, 0.1, 0.1, 0.1)
    q_resolution: str = "encoder"
    periods: int = 1
    warmup_periods: int = 0
    rate: float = 1000.0
    seed: int | None = None
    with_derivatives: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "trajectory", optional_path(self.trajectory))
        if self.trajectory is None:
            raise ValueError("give the trajectory: trajectory=... (--trajectory FILE, oed design's output)")
        check_choice("controller", self.controller, CONTROLLERS)
        object.__setattr__(self, "noise_wrench", tuple(self.noise_wrench))


def effect_values(text: str | None) -> dict[str, Any]:
    """``--effect-values``: JSON text or a JSON file of it."""
    if text is None:
        return {}
    path = Path(text)
    if not text.lstrip().startswith("{"):
        if text.lstrip().startswith(("[", '"')) or text.strip() in ("null", "true", "false"):
            raise ValueError(f"--effect-values must be a JSON object {{effect: value(s)}}, got {text}")
        if not path.exists():
            raise FileNotFoundError(f"--effect-values: {text!r} is neither JSON text nor an existing file")
        text = path.read_text()
    try:
        values = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"--effect-values is not valid JSON: {error}") from None
    if not isinstance(values, dict):
        raise ValueError("--effect-values must be a JSON object keyed by effect name")
    return values


def resolution(text: str) -> Any:
    """``--q-resolution``: a number, ``encoder`` or ``none``."""
    if text.strip().lower() in ("encoder", "none"):
        return None if text.strip().lower() == "none" else "encoder"
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"--q-resolution must be a number, 'encoder' or 'none', got {text!r}") from None


def controller_of(name: str, simulator: Simulator, bandwidth: float) -> Any:
    """The tracking controller: PD, or computed torque with the nominal model (the description's inertias and the
    true viscous friction)."""
    robot = simulator.robot
    if name == "pd":
        return simulator.default_controller(bandwidth)
    model = build_model(robot, "internal", ("viscous",))
    viscous = [effect.values for effect in simulator.effects if isinstance(effect, Viscous)]  # type: ignore[union-attr]
    theta = model.nominal_parameters(viscous=viscous[0] if viscous else 0.0)
    kp, kd = computed_torque_gains(bandwidth_hz=bandwidth, n_joints=robot.n_joints)
    return ComputedTorqueController.from_model(model, theta, kp=kp, kd=kd, label="computed torque, nominal model")


@dataclass(frozen=True)
class SimulateRun:
    """What ``oed simulate`` computed: ``result`` (the simulator's), the truth document, the line it prints and the
    warnings."""

    result: Any = field(repr=False)
    metadata: dict[str, Any] = field(repr=False)
    lines: tuple[str, ...]
    warnings: tuple[str, ...]

    @property
    def measurements(self) -> Any:
        """The simulated :class:`~dynamics.measurements.Measurements`."""
        return self.result.measurements

    def to_dict(self, data: str | Path | None = None) -> dict[str, Any]:
        """The truth JSON (``--truth``); ``data``: the data file it names (``None`` until written)."""
        return {**copy.deepcopy(self.metadata), "data": None if data is None else str(data)}

    def summary(self) -> list[str]:
        """The line ``oed simulate`` prints (without ``; wrote OUT``)."""
        return list(self.lines)

    def write(self, out: str | Path, *, truth: str | Path | None = None) -> None:
        """The data at ``out`` (.csv or .parquet) and, with ``truth``, the truth JSON: both or neither."""
        if Path(out).suffix.lower() not in DATA_SUFFIXES:
            raise ValueError(f"--out {out}: use a .csv or .parquet file")
        with OutputFiles() as outputs:  # the data and the truth file, or neither
            self.result.measurements.write(outputs.stage(out), staged=False)
            if truth is not None:
                with outputs.open(truth) as stream:
                    stream.write(json_text(self.to_dict(out)))


def simulate(**options: Any) -> SimulateRun:
    """``oed simulate``: the robot (``robot`` or ``urdf``) tracking ``trajectory`` (a path to oed design's JSON)
    with the options of the verb by their names (:class:`SimulateOptions`)."""
    args = SimulateOptions(**options)
    if len(args.noise_wrench) not in (1, 6):
        raise ValueError("--noise-wrench takes one value or six")
    robot = robot_of(args)
    trajectory = FourierTrajectory.load(args.trajectory)
    if trajectory.n_joints != robot.n_joints:
        raise ValueError(
            f"trajectory {args.trajectory} has {trajectory.n_joints} joints, the robot {robot.name} has {robot.n_joints}"
        )
    notes = []
    designed_for = trajectory.metadata.get("robot")
    if designed_for and designed_for != robot.name:
        notes.append(f"{args.trajectory} was designed for {designed_for}, and is played on {robot.name}: its bounds "
                     "were not checked for this robot")
    values = effect_values(args.effect_values)
    if is_friction_document(values):  # the friction.json of `oed export`
        effects, friction_notes = effects_from_friction(values, robot, args.effects)
        notes.extend(friction_notes)
    else:
        effects = effects_from_names(args.effects, robot, values)
    noise = NoiseModel(args.noise_tau, tuple(args.noise_wrench), resolution(args.q_resolution))
    simulator = Simulator(robot, effects, noise=noise, rate_hz=args.rate)
    controller = controller_of(args.controller, simulator, args.bandwidth)
    reference, duration = playable(trajectory, args.rate, args.periods, args.warmup_periods)
    result = simulator.run(
        reference, controller, periods=args.periods, duration=duration, warmup_periods=args.warmup_periods,
        with_derivatives=args.with_derivatives, seed=args.seed,
    )
    metadata = dict(result.metadata, trajectory=str(args.trajectory))
    error = np.abs(result.tracking_error).max(axis=0)
    line = (f"{robot.name}: {result.t.shape[0]} samples over {result.t[-1] + 1 / args.rate:.3f} s at {args.rate:g} Hz "
            f"({result.t.shape[0] / result.elapsed_s:.0f} steps/s); effects: "
            f"{', '.join(effect.name for effect in simulator.effects)}; "  # type: ignore[union-attr]
            f"max tracking error {np.array2string(error, precision=4)}")
    return SimulateRun(result, metadata, (line,), tuple(notes))
