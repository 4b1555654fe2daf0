"""The KUKA LWR4+ measurements of FloBaRoID (real joint torques of a 7-joint arm).

Each run is a NumPy ``.npz`` archive (5 027 samples at about 200 Hz) with the keys ``times``
(absolute time stamps, s), ``positions`` (rad), ``velocities`` (rad/s), ``accelerations``
(rad/s², already derived and filtered by FloBaRoID) and ``torques`` (N·m), each ``(N, 7)``
(plus the ``target_*`` references, not used). Source: kjyv/FloBaRoID, LGPL-3.0; the files live
in ``../shared/data/kuka_lwr4/`` beside the checkout and are never copied into the repository.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dynamics.measurements import Measurements

KUKA_KEYS: tuple[str, ...] = ("times", "positions", "velocities", "accelerations", "torques")


def load_kuka_run(path: str | Path) -> Measurements:
    """One run as :class:`Measurements` (time from 0, torques as ``tau``), with checks.

    The time stamps jitter (steps from about 3 to 7 ms around 5 ms); the velocities and
    accelerations are those of the file, so the data are used as sampled, not resampled.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"KUKA measurement file not found: {path}")
    with np.load(path) as archive:
        missing = [key for key in KUKA_KEYS if key not in archive.files]
        if missing:
            raise ValueError(f"{path}: missing key(s) {', '.join(missing)}; expected {', '.join(KUKA_KEYS)}")
        data = {key: np.asarray(archive[key], dtype=float) for key in KUKA_KEYS}
    t = data["times"].reshape(-1)
    n_samples = t.shape[0]
    for key in KUKA_KEYS[1:]:
        if data[key].ndim != 2 or data[key].shape[0] != n_samples:
            raise ValueError(f"{path}: {key} has shape {data[key].shape}, expected ({n_samples}, n_joints)")
        if not np.all(np.isfinite(data[key])):
            raise ValueError(f"{path}: {key} holds NaN or inf")
    if np.any(np.diff(t) <= 0):
        raise ValueError(f"{path}: times are not strictly increasing")
    return Measurements(
        t - t[0], data["positions"], data["velocities"], data["accelerations"], data["torques"], None,
        {"source": str(path), "start_time": float(t[0])},
    )
