"""Robot descriptions and symbolic identification models (CasADi): ``from dynamics import load_robot, build_model``."""

from __future__ import annotations

import importlib
from typing import Any

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "BUILT_IN_ROBOTS": "dynamics.robots",
    "ConsistencyBoundsError": "dynamics.physical_parameters",
    "CouplingShapeError": "dynamics.transmission",
    "DHLink": "dynamics.dh",
    "IdentificationModel": "dynamics.models",
    "InconsistentBodyError": "dynamics.physical_parameters",
    "JointType": "dynamics.robot",
    "LINK_PARAMETER_NAMES": "dynamics.robot",
    "LinkBounds": "dynamics.physical_parameters",
    "Measurements": "dynamics.measurements",
    "ModelKind": "dynamics.models",
    "N_LINK_PARAMETERS": "dynamics.robot",
    "PhysicalParametrisation": "dynamics.physical_parameters",
    "RobotDescriptionError": "dynamics.errors",
    "RobotModel": "dynamics.robot",
    "SampleShapeError": "dynamics.errors",
    "SingularCouplingError": "dynamics.transmission",
    "Transmission": "dynamics.transmission",
    "TransmissionError": "dynamics.transmission",
    "TransmissionSignError": "dynamics.transmission",
    "UnknownJointError": "dynamics.transmission",
    "build_model": "dynamics.models",
    "check_in_ranges": "dynamics.signal_checks",
    "check_informative": "dynamics.signal_checks",
    "check_power_signs": "dynamics.transmission",
    "check_states": "dynamics.models",
    "check_uniform_time": "dynamics.signal_checks",
    "compare_fusion": "dynamics.kalman",
    "consistency_margin": "dynamics.physical_parameters",
    "dh_forward_kinematics": "dynamics.dh",
    "from_pseudo_inertia": "dynamics.physical_parameters",
    "inertial_parameters": "dynamics.robot",
    "is_consistent": "dynamics.physical_parameters",
    "joint_columns": "dynamics.measurements",
    "kalman_fusion": "dynamics.kalman",
    "kalman_step_function": "dynamics.kalman",
    "link_from_psi": "dynamics.physical_parameters",
    "link_summary": "dynamics.physical_parameters",
    "load_robot": "dynamics.robots",
    "log_cholesky_from_link": "dynamics.physical_parameters",
    "log_cholesky_link": "dynamics.physical_parameters",
    "log_det_divergence": "dynamics.physical_parameters",
    "project_link": "dynamics.physical_parameters",
    "pseudo_inertia": "dynamics.physical_parameters",
    "puma560_transmission": "dynamics.transmission",
    "random_states": "dynamics.base_parameters",
    "rank_deficiency_message": "dynamics.signal_checks",
    "robot_from_dh": "dynamics.dh",
    "robot_from_urdf": "dynamics.urdf",
    "robot_mjcf": "dynamics.mjcf_export",
    "robot_urdf": "dynamics.urdf_export",
    "single_channel": "dynamics.signal_checks",
    "to_pinocchio": "dynamics.pinocchio_bridge",
    "transmission_from_json": "dynamics.transmission_files",
    "transmission_from_urdf": "dynamics.transmission_files",
    "urdf_with_inertials": "dynamics.urdf_export",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    """The names of ``__all__``, imported from their modules when first asked for (PEP 562)."""
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
