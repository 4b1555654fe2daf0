"""The force a MuJoCo actuator makes from its control and the state: ``f = gain(l, v) ctrl + bias(l, v)``.

MuJoCo's actuator model (MuJoCo documentation, "Computation", Actuation model; XML reference, ``<actuator>``): for
an actuator without activation dynamics (``dyntype`` none), with the control ``u`` clamped to ``ctrlrange`` where
it is limited, the actuator's length ``l = g q`` and velocity ``v = g q̇`` through a joint transmission of gear
``g``,

    f = (g0 + g1 l + g2 v) u + b0 + b1 l + b2 v,

the gain affine (``gaintype`` affine; fixed: ``g1 = g2 = 0``) and the bias affine (``biastype`` affine; none:
``b = 0``), ``f`` clamped to ``forcerange`` where it is limited; the joint's torque is ``τ = g f``, clamped to the
joint's ``actuatorfrcrange`` where limited. The shortcuts set them: ``<motor>`` ``gain 1``; ``<position kp kv>``
``gain kp``, ``bias (0, -kp, -kv)``; ``<velocity kv>`` ``gain kv``, ``bias (0, 0, -kv)``; ``<damper kv>`` gain
``(0, 0, -kv)``.

So a log of a servo's controls (``ctrl``: a setpoint) with the joints' positions and velocities gives its force
when the MJCF that defines the servo is at hand (:func:`dynamics.mjcf.mjcf_servos`). Actuators with activation
dynamics (``timeconst``, ``<intvelocity>``, ``<cylinder>``, ``<muscle>``) have a state of their own that the log
does not hold: not a servo law here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True, eq=False)
class ServoLaws:
    """Each joint's actuator law, MuJoCo's (module docstring), one row a joint in the robot's order.

    Parameters
    ----------
    gear
        ``(n,)`` ``g``: the joint's torque per unit of actuator force, its length per unit of joint motion.
    gain
        ``(n, 3)`` ``(g0, g1, g2)`` of the gain.
    bias
        ``(n, 3)`` ``(b0, b1, b2)`` of the bias.
    ctrl_range
        ``(n, 2)`` the control's limits (``±inf`` where not limited).
    force_range
        ``(n, 2)`` the actuator force's limits (``±inf`` where not limited).
    torque_range
        ``(n, 2)`` the joint's actuator torque limits (``actuatorfrcrange``; ``±inf`` where not limited).
    actuators
        The actuators' labels (``<position name='a1'>``), for messages.
    source
        Where the laws come from (``MJCF arm.xml <actuator>``).
    """

    gear: NDArray[np.float64]
    gain: NDArray[np.float64]
    bias: NDArray[np.float64]
    ctrl_range: NDArray[np.float64]
    force_range: NDArray[np.float64]
    torque_range: NDArray[np.float64]
    actuators: tuple[str, ...] = ()
    source: str = ""

    def __post_init__(self) -> None:
        n = np.asarray(self.gear).shape[0]
        for name, shape in (("gear", (n,)), ("gain", (n, 3)), ("bias", (n, 3)), ("ctrl_range", (n, 2)),
                            ("force_range", (n, 2)), ("torque_range", (n, 2))):
            value = np.array(getattr(self, name), dtype=float)
            if value.shape != shape:
                raise ValueError(f"servo laws: {name} has shape {value.shape}, expected {shape}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def n_joints(self) -> int:
        return int(self.gear.shape[0])

    def truncated(self, n_joints: int) -> ServoLaws:
        """The laws of the first ``n_joints`` joints."""
        return ServoLaws(self.gear[:n_joints], self.gain[:n_joints], self.bias[:n_joints], self.ctrl_range[:n_joints],
                         self.force_range[:n_joints], self.torque_range[:n_joints], self.actuators[:n_joints],
                         self.source)

    @property
    def uses_velocity(self) -> bool:
        """Whether any law depends on the joints' velocities (a damping gain ``kv``, a velocity servo)."""
        return bool(np.any(self.gain[:, 2] != 0) or np.any(self.bias[:, 2] != 0))

    def forces(self, ctrl: ArrayLike, q: ArrayLike, dq: ArrayLike | None) -> NDArray[np.float64]:
        """``(N, n)`` the actuators' forces ``f`` for ``(N, n)`` controls, joint positions and velocities
        (``dq`` may be ``None`` when no law uses it: :attr:`uses_velocity`)."""
        ctrl = np.clip(np.asarray(ctrl, dtype=float), self.ctrl_range[:, 0], self.ctrl_range[:, 1])
        length = np.asarray(q, dtype=float) * self.gear
        if dq is None:
            if self.uses_velocity:
                raise ValueError("the servo laws use the joints' velocities: give dq")
            velocity = np.zeros_like(length)
        else:
            velocity = np.asarray(dq, dtype=float) * self.gear
        gain = self.gain[:, 0] + self.gain[:, 1] * length + self.gain[:, 2] * velocity
        bias = self.bias[:, 0] + self.bias[:, 1] * length + self.bias[:, 2] * velocity
        return np.clip(gain * ctrl + bias, self.force_range[:, 0], self.force_range[:, 1])

    def joint_torques(self, ctrl: ArrayLike, q: ArrayLike, dq: ArrayLike | None) -> NDArray[np.float64]:
        """``(N, n)`` the joints' actuator torques ``τ = g f`` (MuJoCo's ``qfrc_actuator``), clamped to each joint's
        ``actuatorfrcrange``."""
        return np.clip(self.gear * self.forces(ctrl, q, dq), self.torque_range[:, 0], self.torque_range[:, 1])

    def to_dict(self) -> dict[str, object]:
        """The JSON form :meth:`from_dict` reads (a transmission file's ``servos``): unlimited ranges as ``null``."""
        def bounds(values: NDArray[np.float64]) -> list[list[float | None]]:
            return [[None if not np.isfinite(value) else float(value) for value in row] for row in values]

        return {"gear": self.gear.tolist(), "gain": self.gain.tolist(), "bias": self.bias.tolist(),
                "ctrl_range": bounds(self.ctrl_range), "force_range": bounds(self.force_range),
                "torque_range": bounds(self.torque_range), "actuators": list(self.actuators), "source": self.source}

    @classmethod
    def from_dict(cls, document: Mapping[str, Any], where: str = "servos") -> ServoLaws:
        """The laws of :meth:`to_dict`'s form; ``ValueError`` naming ``where`` for anything else."""
        if not isinstance(document, Mapping):
            raise ValueError(f"{where}: an object with gear, gain, bias and ranges, got {document!r}")
        try:
            def bounds(name: str) -> NDArray[np.float64]:
                rows = document.get(name)
                if rows is None:
                    return np.tile([-np.inf, np.inf], (len(document["gear"]), 1))
                return np.array([[(-np.inf, np.inf)[index] if value is None else float(value)
                                  for index, value in enumerate(row)] for row in rows], dtype=float)

            return cls(np.asarray(document["gear"], dtype=float), np.asarray(document["gain"], dtype=float),
                       np.asarray(document["bias"], dtype=float), bounds("ctrl_range"),
                       bounds("force_range"), bounds("torque_range"),
                       tuple(str(label) for label in document.get("actuators", ())), str(document.get("source", "")))
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(f"{where}: not servo laws ({error})") from None
