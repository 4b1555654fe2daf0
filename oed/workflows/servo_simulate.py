"""``oed servo-simulate`` as a library call: the simulated servo arm driven by an APRBS CSV; ``t, u1..uJ, q1..qJ``
(and the raw sensor columns) written by :meth:`ServoSimulateRun.write`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dynamics.simulation.servo_simulator import PAPER_JOINTS, simulate_servo_arm
from estimation.servo.files import read_csv, write_csv

__all__ = ["ServoSimulateRun", "servo_simulate"]


@dataclass(frozen=True)
class ServoSimulateRun:
    """The simulated record (``record``) and the columns written."""

    record: Any = field(repr=False)
    columns: dict[str, Any] = field(repr=False)

    def summary(self) -> list[str]:
        """The line ``oed servo-simulate`` prints after ``wrote OUT: ``."""
        return [f"{self.record.t.size} samples, columns {', '.join(self.columns)}"]

    def write(self, out: str | Path) -> None:
        """The CSV at ``out``."""
        write_csv(out, self.columns)


def servo_simulate(*, aprbs: str | Path, raw: bool = False, no_gravity: bool = False, max_speed: float = 5.2,
                   seed: int | None = None) -> ServoSimulateRun:
    """``oed servo-simulate``: the servo arm (Kalman-fused angles) driven by the APRBS CSV ``aprbs``
    (columns t, u1..u4 [rad])."""
    table = read_csv(aprbs, required=("t", "u1"))
    u = table.stack("u")
    if u.shape[1] != len(PAPER_JOINTS):
        raise ValueError(f"{aprbs}: the servo arm has {len(PAPER_JOINTS)} joints, found columns u1..u{u.shape[1]}")
    record = simulate_servo_arm(table.t, u, gravity=not no_gravity, max_speed=max_speed, seed=seed)
    n = u.shape[1]
    columns = {"t": record.t, **{f"u{j + 1}": record.u[:, j] for j in range(n)},
               **{f"q{j + 1}": record.q[:, j] for j in range(n)}}
    if raw:
        for name, values in (("gyro", record.gyro), ("acc_angle", record.acc_angle), ("q_true", record.q_true)):
            columns.update({f"{name}{j + 1}": values[:, j] for j in range(n)})
    return ServoSimulateRun(record, columns)
