"""Does the linear servo model describe a joint? Its free-run error held to the angle noise.

The second-order joint model of the servo paper (eq. 11) is linear. A hobby servo is not, wherever its drive
saturates (a rated speed), its gears have backlash or its controller a dead zone. The one-step-ahead predictor
hides that: it is corrected by the measured angle at every sample, so its error stays near the noise whatever the
model lacks. The free-run simulation is not corrected, and drifts away where the joint leaves the linear model.
Measured on ``oed servo-simulate`` data (an APRBS, Kalman-fused angles, the paper's joints):

============================  =========================  =========================  ==================
drive                          free-run / yardstick, OE   free-run / yardstick, ERLS  ``b`` of joint 1, OE
============================  =========================  =========================  ==================
linear (no speed limit)        1.65 -- 1.95               2.5 -- 3.2                  19.0 (true 19.1)
saturating at 5.2 rad/s        16 -- 28                   16 -- 30                    7.3 (true 19.1)
============================  =========================  =========================  ==================

(a 60 s APRBS of ``oed aprbs --joints 4 --duration 60 --dt 0.01 --seed 1``, 80 % to estimate).

The yardstick is the larger of two noise levels: the angle noise estimated without the model (the difference
estimator of :mod:`estimation.uncertainty.noise_floor` on the validation angles), when the angles allow one,
and the one-step-ahead error, the noise a predictor corrected at every sample leaves (said in ``method``). The
larger, because Kalman-fused angles are filtered: the difference estimator mostly refuses them, and where it
does not it reads a noise too low (0.0017 rad against a one-step error of 0.004 rad on the table's data), which
would call a linear joint non-linear. A joint whose free-run RMSE exceeds :data:`FREE_RUN_LIMIT` times the
yardstick is not described by the linear model, and the fit says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from estimation.uncertainty.noise_floor import NoiseFloorError, difference_variance

__all__ = ["FREE_RUN_LIMIT", "FreeRunCheck", "check_free_run"]

#: free-run RMSE over the angle noise beyond which the linear model does not describe the joint
FREE_RUN_LIMIT = 5.0


@dataclass(frozen=True)
class FreeRunCheck:
    """One joint's free-run error against its angle noise.

    Attributes
    ----------
    joint
        1-based joint number.
    noise_std
        The yardstick, rad.
    method
        ``differences`` (model-free, from the validation angles) or ``one-step`` (the one-step-ahead RMSE): the
        larger of the two.
    ratio
        Free-run RMSE over ``noise_std``.
    """

    joint: int
    noise_std: float
    method: Literal["differences", "one-step"]
    ratio: float

    @property
    def described(self) -> bool:
        """Whether the linear model describes the joint (``ratio`` within :data:`FREE_RUN_LIMIT`)."""
        return bool(self.ratio <= FREE_RUN_LIMIT)

    def to_dict(self) -> dict[str, Any]:
        """``{angle_noise_std, angle_noise_method, free_run_over_noise, linear_model_describes}``."""
        return {"angle_noise_std": self.noise_std, "angle_noise_method": self.method,
                "free_run_over_noise": self.ratio, "linear_model_describes": self.described}

    def warning(self) -> str | None:
        """The message for a joint the linear model does not describe, else ``None``."""
        if self.described:
            return None
        yardstick = "its angle noise" if self.method == "differences" else "its one-step-ahead error (the angle noise)"
        return (f"joint {self.joint}: the free-run error is {self.ratio:.3g} times {yardstick} "
                f"({self.noise_std:.3g} rad): the linear second-order model does not describe this joint (a drive that "
                "saturates at a speed limit, backlash or a dead zone?); its b, k, sigma and their standard deviations "
                "are not to be trusted")


def check_free_run(joint: int, q_validation: ArrayLike, rmse_free_run: float, rmse_one_step: float) -> FreeRunCheck:
    """The free-run check of one joint (module docstring) from its validation angles and the fit's two RMSEs."""
    q_validation = np.asarray(q_validation, dtype=float).reshape(-1, 1)
    noise, method = float(rmse_one_step), "one-step"
    try:
        variance, _ = difference_variance(q_validation)
        if np.sqrt(variance[0]) > noise:
            noise, method = float(np.sqrt(variance[0])), "differences"
    except NoiseFloorError:
        pass
    ratio = float(rmse_free_run / noise) if noise > 0 else float("inf")
    return FreeRunCheck(int(joint), noise, method, ratio)
