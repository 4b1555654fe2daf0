"""Read-only loaders of the shared real data sets (never copied into the repository).

* EMPS (Janot, Gautier & Brunot, electro-mechanical positioning system): :func:`load_emps`.
* DaISy 96-009 flexible robot arm (KU Leuven): :func:`load_daisy_robot_arm`.

Both take either the file itself or the folder holding it (e.g. ``../shared/data/emps``) and raise
``OSError`` naming the missing file.

Examples
--------
>>> from estimation.datasets.shared import load_emps                                   # doctest: +SKIP
>>> data = load_emps("../shared/data/emps", which="validation")                 # doctest: +SKIP
>>> data.force.shape, data.dt                                                   # doctest: +SKIP
((24841,), 0.001)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from dynamics.measurements import Measurements
from estimation.preprocessing.differentiation import ButterworthDifferentiation, fill_derivatives

EMPS_FILES = {"estimation": "DATA_EMPS.mat", "validation": "DATA_EMPS_PULSES.mat"}
DAISY_FILE = "robot_arm.dat"


@dataclass(frozen=True)
class EMPSData:
    """One EMPS record (MATLAB file of the benchmark), SI units.

    Attributes
    ----------
    t
        Time [s] (N,).
    qm
        Motor (axis) position [m].
    qg
        Reference position of the closed loop [m].
    vir
        Controller output voltage [V].
    force
        Applied motor force ``gtau · vir`` [N].
    gtau
        Drive gain [N/V] (about 35.15).
    kp, kv
        Position and velocity loop gains of the benchmark's controller.
    pulses
        External force pulses [N] (validation file only, else ``None``).
    dt
        Sample time [s] (median step of ``t``).
    which
        ``"estimation"`` or ``"validation"``.
    source
        The file read.
    """

    t: np.ndarray
    qm: np.ndarray
    qg: np.ndarray
    vir: np.ndarray
    force: np.ndarray
    gtau: float
    kp: float
    kv: float
    pulses: np.ndarray | None
    dt: float
    which: str
    source: Path


def _resolve(path_or_dir: str | Path, name: str) -> Path:
    path = Path(path_or_dir)
    if path.is_dir():
        path = path / name
    if not path.is_file():
        raise OSError(f"data file {str(path)!r} not found (expected {name} of the shared data folder)")
    return path


def load_emps(path_or_dir: str | Path, which: Literal["estimation", "validation"] = "estimation") -> EMPSData:
    """Load ``DATA_EMPS.mat`` (``which="estimation"``) or ``DATA_EMPS_PULSES.mat`` (``"validation"``).

    ``path_or_dir`` is the folder holding the files or a ``.mat`` file itself (then ``which`` is only a label).
    """
    import scipy.io

    if which not in EMPS_FILES:
        raise ValueError(f"which must be 'estimation' or 'validation', got {which!r}")
    path = _resolve(path_or_dir, EMPS_FILES[which])
    raw = scipy.io.loadmat(path)
    missing = [key for key in ("t", "qm", "qg", "vir", "gtau") if key not in raw]
    if missing:
        raise ValueError(f"{path.name}: missing variable(s) {', '.join(missing)}")
    column = lambda key: np.asarray(raw[key], dtype=float).reshape(-1)  # noqa: E731
    t, vir = column("t"), column("vir")
    gtau = float(np.asarray(raw["gtau"]).reshape(-1)[0])
    scalar = lambda key: float(np.asarray(raw[key]).reshape(-1)[0]) if key in raw else float("nan")  # noqa: E731
    return EMPSData(
        t=t, qm=column("qm"), qg=column("qg"), vir=vir, force=gtau * vir, gtau=gtau, kp=scalar("kp"), kv=scalar("kv"),
        pulses=column("pulses_N") if "pulses_N" in raw else None, dt=float(np.median(np.diff(t))), which=which, source=path,
    )


@dataclass(frozen=True)
class DaisyRobotArm:
    """DaISy 96-009: ``u`` reaction torque of the structure, ``y`` acceleration of the flexible arm (1024 samples,
    no sampling time given in the file; samples are used as the time unit)."""

    u: np.ndarray
    y: np.ndarray
    source: Path


def load_daisy_robot_arm(path_or_dir: str | Path) -> DaisyRobotArm:
    """Load ``robot_arm.dat`` (two whitespace-separated columns: input, output)."""
    path = _resolve(path_or_dir, DAISY_FILE)
    data = np.loadtxt(path, ndmin=2)
    if data.shape[1] != 2:
        raise ValueError(f"{path.name}: expected 2 columns (input, output), found {data.shape[1]}")
    return DaisyRobotArm(u=data[:, 0].copy(), y=data[:, 1].copy(), source=path)


def emps_measurements(
    path_or_dir: str | Path,
    which: Literal["estimation", "validation"] = "estimation",
    *,
    cutoff_hz: float = 20.0,
    trim: int = 500,
    decimation: int = 10,
):
    """An EMPS record as :class:`~dynamics.measurements.Measurements` of the one-joint ``emps`` robot.

    ``tau1`` is the motor force ``gtau·vir`` (the external pulses of the validation file are not
    added: their sign and point of application are not documented). Velocity and acceleration
    come from a zero-phase Butterworth filter, as the benchmark's description recommends, the force kept as recorded
    (the fit's target, ``ButterworthDifferentiation``'s default ``torques="recorded"``) (the derivatives those of the filtered positions' quintic spline, not its central differences:
    :func:`~estimation.preprocessing.differentiation.spline_derivatives`); ``trim`` samples at each end (filter transients)
    are dropped, then the record is decimated by ``decimation`` (1 kHz → 100 Hz by default).
    """
    data = load_emps(path_or_dir, which)
    raw = Measurements(t=data.t, q=data.qm[:, None], tau=data.force[:, None], metadata={"source": str(data.source)})
    filled = fill_derivatives(raw, ButterworthDifferentiation(cutoff_hz=cutoff_hz), decimation=1)
    kept = filled.select(slice(trim, filled.n_samples - trim))
    return kept.select(slice(None, None, decimation))
