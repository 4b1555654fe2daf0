"""The gyro/accelerometer Kalman fusion now lives in :mod:`dynamics.kalman`: it is part of how the
servo arm measures its angle (the simulator reports the fused angle, as the arm does), and the
output-error estimator predicts through the same filter. Re-exported here so that existing imports keep working.
"""

from dynamics.kalman import (  # noqa: F401
    FusionResult,
    kalman_step_function,
    _kalman_run,
    kalman_fusion,
    integrated_gyro,
    FusionComparison,
    compare_fusion,
)

__all__ = ["FusionResult", "kalman_step_function", "kalman_fusion", "integrated_gyro", "FusionComparison", "compare_fusion"]
