"""Use a consistent estimate: simulate it, control with it, check its mass matrix.

An unconstrained base-parameter estimate cannot be simulated: forward dynamics needs the standard
parameters of every link, and least squares gives only their base combinations, which no rigid
body may realise. A :class:`estimation.consistent.least_squares.ConsistentEstimate` holds real bodies, so::

    simulator = consistent_simulator(model, estimate)            # dynamics.simulation.simulator.Simulator
    controller = consistent_controller(model, estimate)          # computed torque on Y(q, dq, ddq) θ
    result = simulator.run(measured_reference(run3), controller, duration=run3.t[-1])
    mass_matrix_eigenvalues(consistent_robot(model, estimate), result.q).min() > 0

The simulated friction is the estimate's: viscous, Coulomb (``tanh(dq / 0.05)``, the simulator's
continuous law, where the identification model has ``sign``), offsets and armature; plate offsets do
not move the robot and are left out.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.simulation.controllers import ComputedTorqueController, computed_torque_gains
from dynamics.effects.linear import CoulombFriction
from dynamics.effects.shaped import is_shaped
from dynamics.models import IdentificationModel, build_model
from dynamics.robot import RobotModel
from dynamics.simulation.sensors import NoiseModel
from dynamics.simulation.joint_effects import SimulatedArmature, Coulomb, Offset, Viscous
from dynamics.simulation.simulator import Simulator
from estimation.consistent.least_squares import ConsistentEstimate
from dynamics.measurements import Measurements

#: identification-model symbol -> simulated effect
SIMULATED_EFFECTS = {"fv": Viscous, "fc": Coulomb, "off": Offset, "Ia": SimulatedArmature}
#: effects that do not act on the motion (force-plate offsets)
NOT_SIMULATED = ("wrench_offset",)


def consistent_robot(model: IdentificationModel, estimate: ConsistentEstimate) -> RobotModel:
    """``model``'s robot carrying the estimated links (:meth:`RobotModel.with_parameters`)."""
    return model.robot.with_parameters(estimate.theta[: 10 * model.robot.n_joints])


def simulated_effects(model: IdentificationModel, estimate: ConsistentEstimate, *,
                      coulomb_smoothing: float = 0.05) -> tuple:
    """The estimate's joint effects as :mod:`dynamics.simulation.joint_effects` objects (one value per joint)."""
    n = model.robot.n_joints
    values: dict[str, NDArray[np.float64]] = {}
    for effect in model.effects:
        if effect.name in NOT_SIMULATED:
            continue
        if is_shaped(effect, model.robot):
            raise ValueError(f"effect {getattr(effect, 'spec', effect.name)!r} has fitted shape parameters the "
                             "simulator's joint effects do not take (its Coulomb law has one smoothing for all "
                             f"joints); simulate {', '.join(SIMULATED_EFFECTS)} only")
        names = effect.parameter_names(model.robot)
        for name in names:
            symbol = name.rstrip("0123456789")
            if symbol not in SIMULATED_EFFECTS or not name[len(symbol):].isdigit():
                raise ValueError(f"effect {effect.name!r} ({name}) has no simulated counterpart; simulate "
                                 f"{', '.join(SIMULATED_EFFECTS)} only")
            values.setdefault(symbol, np.zeros(n))[int(name[len(symbol):]) - 1] = estimate.effect_values()[name]
    effects = []
    for symbol, per_joint in values.items():
        kind = SIMULATED_EFFECTS[symbol]
        effects.append(kind(tuple(per_joint), smoothing=coulomb_smoothing) if kind is Coulomb else kind(tuple(per_joint)))
    return tuple(effects)


def consistent_simulator(model: IdentificationModel, estimate: ConsistentEstimate, *,
                         noise: NoiseModel | None = None, rate_hz: float = 1000.0) -> Simulator:
    """A :class:`dynamics.simulation.simulator.Simulator` of the identified robot (noise-free sensors by default)."""
    noise = NoiseModel(tau_std=0.0, wrench_std=0.0, q_resolution=None) if noise is None else noise
    return Simulator(consistent_robot(model, estimate), effects=simulated_effects(model, estimate), noise=noise,
                     rate_hz=rate_hz)


def consistent_controller(model: IdentificationModel, estimate: ConsistentEstimate, *, bandwidth_hz: float = 4.0,
                          damping: float = 1.0, coulomb_smoothing: float | None = 0.05) -> ComputedTorqueController:
    """Computed torque with ``Y(q, dq, ddq) θ`` on the estimate's standard parameters (links and effects).

    ``coulomb_smoothing``: the controller's Coulomb law ``tanh(dq / smoothing)``, the simulator's
    (``None``: the model's own, ``sign`` unless it says otherwise)."""
    kp, kd = computed_torque_gains(bandwidth_hz=bandwidth_hz, damping=damping, n_joints=model.robot.n_joints)
    if coulomb_smoothing is not None and any(isinstance(effect, CoulombFriction) for effect in model.effects):
        effects = [CoulombFriction(effect.joints, smoothing=coulomb_smoothing) if isinstance(effect, CoulombFriction)
                   else effect for effect in model.effects]
        model = build_model(model.robot, model.kind, effects)
    return ComputedTorqueController.from_model(model, estimate.theta, kp=kp, kd=kd, label="computed torque, consistent")


def mass_matrix_eigenvalues(robot: RobotModel, q: ArrayLike, armature: ArrayLike | None = None) -> NDArray[np.float64]:
    """Smallest eigenvalue of the joint-space mass matrix ``M(q)`` (plus armature) at each row of ``q``."""
    import pinocchio as pin

    from dynamics.pinocchio_bridge import to_pinocchio

    pinocchio_model = to_pinocchio(robot)
    if armature is not None:
        pinocchio_model.armature = np.asarray(armature, dtype=float)
    data = pinocchio_model.createData()
    smallest = []
    for state in np.atleast_2d(np.asarray(q, dtype=float)):
        M = pin.crba(pinocchio_model, data, state)
        M = np.triu(M) + np.triu(M, 1).T
        smallest.append(np.linalg.eigvalsh(M)[0])
    return np.array(smallest)


def measured_reference(measurements: Measurements) -> Callable[[NDArray], tuple[NDArray, NDArray, NDArray]]:
    """``t -> (q_d, dq_d, ddq_d)``: a recorded motion, linearly interpolated, as a simulator reference."""
    if measurements.dq is None or measurements.ddq is None:
        raise ValueError("the reference needs dq and ddq (estimation.preprocessing.differentiation.fill_derivatives)")
    t = measurements.t

    def reference(times: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        times = np.asarray(times, dtype=float)
        return tuple(np.column_stack([np.interp(times, t, signal[:, j]) for j in range(signal.shape[1])])
                     for signal in (measurements.q, measurements.dq, measurements.ddq))

    return reference
