"""The servo-arm paper (Paiva et al.): the second-order joint model, its ERLS identification protocol, the output-error fit and the workflow's files.

Modules: :mod:`~estimation.servo.files`, :mod:`~estimation.servo.model`, :mod:`~estimation.servo.output_error`, :mod:`~estimation.servo.output_error_arm`, :mod:`~estimation.servo.output_error_covariance`, :mod:`~estimation.servo.output_error_model`, :mod:`~estimation.servo.protocol`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "FREE_RUN_LIMIT": "estimation.servo.free_run_check",
    "KalmanFusionSettings": "estimation.servo.output_error",
    "OutputErrorDivergedError": "estimation.servo.output_error",
    "OutputErrorInputError": "estimation.servo.output_error",
    "check_free_run": "estimation.servo.free_run_check",
    "discrete_to_gray_box": "estimation.servo.model",
    "fit_servo_arm": "estimation.servo.protocol",
    "fit_servo_arm_output_error": "estimation.servo.output_error_arm",
    "fit_servo_joint": "estimation.servo.protocol",
    "fit_servo_joint_output_error": "estimation.servo.output_error",
    "free_run": "estimation.servo.model",
    "gray_box_to_discrete": "estimation.servo.model",
    "joint_step_function": "estimation.servo.model",
    "read_csv": "estimation.servo.files",
    "write_csv": "estimation.servo.files",
    "write_text_atomic": "estimation.servo.files",
    "zoh_function": "estimation.servo.output_error_model",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
