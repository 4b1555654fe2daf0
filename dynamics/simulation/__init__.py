"""Simulated experiments: the forward-dynamics simulator, the servo-arm simulator, controllers, sensors and the effects the simulator applies; synthetic measurements straight from a model.

Modules: :mod:`~dynamics.simulation.controllers`, :mod:`~dynamics.simulation.effects`, :mod:`~dynamics.simulation.joint_effects`, :mod:`~dynamics.simulation.motor_effects`, :mod:`~dynamics.simulation.plant`, :mod:`~dynamics.simulation.plate_effects`, :mod:`~dynamics.simulation.sensors`, :mod:`~dynamics.simulation.servo_simulator`, :mod:`~dynamics.simulation.simulator`, :mod:`~dynamics.simulation.synthetic`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "SimulatedArmature": "dynamics.simulation.joint_effects",
    "ComputedTorqueController": "dynamics.simulation.controllers",
    "Controller": "dynamics.simulation.controllers",
    "Coulomb": "dynamics.simulation.joint_effects",
    "MotorFriction": "dynamics.simulation.motor_effects",
    "NoiseModel": "dynamics.simulation.sensors",
    "Offset": "dynamics.simulation.joint_effects",
    "PAPER_JOINTS": "dynamics.simulation.servo_simulator",
    "PDController": "dynamics.simulation.controllers",
    "PUMA560_ROTOR_INERTIA": "dynamics.simulation.joint_effects",
    "PlateCable": "dynamics.simulation.plate_effects",
    "PlateOffset": "dynamics.simulation.plate_effects",
    "RegressorInverseDynamics": "dynamics.simulation.controllers",
    "SIMULATED_EFFECTS": "dynamics.simulation.effects",
    "SensorModel": "dynamics.simulation.servo_simulator",
    "ServoJoint": "dynamics.simulation.servo_simulator",
    "SimulationResult": "dynamics.simulation.simulator",
    "Simulator": "dynamics.simulation.simulator",
    "SimulatedSpring": "dynamics.simulation.joint_effects",
    "Viscous": "dynamics.simulation.joint_effects",
    "computed_torque_gains": "dynamics.simulation.controllers",
    "effects_from_friction": "dynamics.simulation.effects",
    "effects_from_names": "dynamics.simulation.effects",
    "encoder_resolution": "dynamics.simulation.sensors",
    "is_friction_document": "dynamics.simulation.effects",
    "is_puma560": "dynamics.simulation.joint_effects",
    "pd_gains": "dynamics.simulation.controllers",
    "puma560_link_friction": "dynamics.simulation.joint_effects",
    "simulate": "dynamics.simulation.synthetic",
    "simulate_controlled": "dynamics.simulation.simulator",
    "simulate_servo_arm": "dynamics.simulation.servo_simulator",
    "true_parameters": "dynamics.simulation.synthetic",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
