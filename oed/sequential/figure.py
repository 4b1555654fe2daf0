"""Figure of the next experiment beside the ones already run, in the state that matters for a friction law.

A Coulomb, Stribeck or sigmoid law shows its shape at low speed: what the first experiment left uncertain
is usually the time it spent near ``dq = 0``. The figure gives, per joint, the share of time spent at each
speed ``|dq|`` (logarithmic bins) by the records and by the designed trajectory (top), and the two motions
in the ``(q, dq)`` plane (bottom).
"""

from __future__ import annotations

import numpy as np

from dynamics.measurements import Measurements
from oed.fourier import FourierTrajectory

__all__ = ["plot_next_experiment"]


def plot_next_experiment(records: Measurements, trajectory: FourierTrajectory, *, rate_hz: float = 1000.0,
                         title: str | None = None):
    """Time share per speed and the ``(q, dq)`` plane of each joint: the records against the designed trajectory.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure  # no pyplot: no backend switch, no global figure registry

    _, q, dq, _ = trajectory.sample(rate_hz)
    n = trajectory.n_joints
    speeds = np.concatenate([np.abs(records.dq).ravel(), np.abs(dq).ravel()])
    positive = speeds[speeds > 0]
    low = max(float(positive.min()) if positive.size else 1e-4, 1e-4)
    edges = np.geomspace(low, max(float(speeds.max()), 2 * low), 30)
    figure = Figure(figsize=(3.4 * n, 6.0))
    axes = figure.subplots(2, n, squeeze=False)
    for joint in range(n):
        axis = axes[0, joint]
        for values, label in ((records.dq[:, joint], "so far"), (dq[:, joint], "designed")):
            share, _ = np.histogram(np.clip(np.abs(values), edges[0], edges[-1]), edges)
            axis.stairs(share / max(values.size, 1), edges, label=label)
        axis.set_xscale("log")
        axis.set_xlabel("|dq| [rad/s]")
        axis.set_title(trajectory.joint_names[joint])
        axis.grid(alpha=0.3)
        phase = axes[1, joint]
        phase.plot(records.q[:, joint], records.dq[:, joint], lw=0.6, alpha=0.7, label="so far")
        phase.plot(q[:, joint], dq[:, joint], lw=1.0, label="designed")
        phase.set_xlabel("q [rad]")
        phase.grid(alpha=0.3)
    axes[0, 0].set_ylabel("share of time")
    axes[1, 0].set_ylabel("dq [rad/s]")
    axes[0, 0].legend()
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    return figure
