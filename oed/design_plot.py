"""Figure of an excitation trajectory with its bounds, like the PUMA paper's Figs. 4–6."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from oed.bounds import JointBounds
from oed.fourier import FourierTrajectory


def plot_trajectory(
    trajectory: FourierTrajectory,
    bounds: JointBounds | None = None,
    *,
    rate_hz: float = 1000.0,
    executed: Sequence[np.ndarray] | None = None,
    title: str | None = None,
    margins: Sequence[dict] = (),
):
    """``q, dq, ddq`` (rows) of each joint (columns) over one period, bounds dashed.

    Parameters
    ----------
    trajectory
        The designed trajectory (eq. 18).
    bounds
        Drawn as dashed lines (eq. 19).
    executed
        Optional ``(t, q, dq, ddq)`` of the trajectory as executed by the robot, drawn on top
        (the paper's "real" trajectories).
    margins
        The constraints' margins over the experiment (:meth:`oed.design_problem.ExcitationDesign.margin_report`:
        ``name, unit, t_s, margin``), drawn in a bottom row over the experiment's time, zero dashed.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure  # no pyplot: no backend switch, no global figure registry

    t, q, dq, ddq = trajectory.sample(rate_hz)
    n = trajectory.n_joints
    rows = 3 + bool(margins)
    figure = Figure(figsize=(3.2 * n, 6.5 + 2.0 * bool(margins)))
    grid = figure.add_gridspec(rows, n)
    axes = np.empty((3, n), dtype=object)
    for row in range(3):
        for joint in range(n):
            axes[row, joint] = figure.add_subplot(grid[row, joint], sharex=axes[0, 0] if row or joint else None)
    labels = ("q [rad]", "dq [rad/s]", "ddq [rad/s²]")
    for row, (values, label) in enumerate(zip((q, dq, ddq), labels)):
        for joint in range(n):
            axis = axes[row, joint]
            axis.plot(t, values[:, joint], lw=1.2, label="optimised")
            if executed is not None:
                axis.plot(executed[0], executed[row + 1][:, joint], lw=0.8, ls="-", alpha=0.8, label="executed")
            if bounds is not None:
                low, high = {
                    0: (bounds.q_min[joint], bounds.q_max[joint]),
                    1: (-bounds.dq_max[joint], bounds.dq_max[joint]),
                    2: (-bounds.ddq_max[joint], bounds.ddq_max[joint]),
                }[row]
                for level in (low, high):
                    axis.axhline(level, color="k", ls="--", lw=0.8)
            if row == 0:
                axis.set_title(trajectory.joint_names[joint])
            if joint == 0:
                axis.set_ylabel(label)
            if row == 2:
                axis.set_xlabel("t [s]")
            axis.grid(alpha=0.3)
    if margins:
        axis = figure.add_subplot(grid[3, :])
        for entry in margins:
            axis.plot(entry["t_s"], entry["margin"], lw=1.0, label=f"{entry['name']} [{entry['unit']}]")
        axis.axhline(0.0, color="k", ls="--", lw=0.8)
        axis.set_xlabel("experiment time [s]")
        axis.set_ylabel("worst margin")
        axis.set_yscale("symlog", linthresh=1e-3)
        axis.legend(fontsize="small")
        axis.grid(alpha=0.3)
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    return figure

