"""Figures of an APRBS: the signal per joint, its amplitude histogram and its power spectrum (Welch)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.signal

from dynamics.runtime.output_files import save_figure
from oed.aprbs_signal import APRBSResult


def plot_aprbs(result: APRBSResult, path: str | Path | None = None):
    """Three-column figure (signal, histogram, spectrum), one row per joint; saved to ``path`` when given.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure  # no pyplot: no backend switch, no global figure registry

    n_joints = result.u.shape[1]
    fs = 1.0 / result.design.dt
    fig = Figure(figsize=(12, 2.4 * n_joints))
    axes = fig.subplots(n_joints, 3, squeeze=False)
    for j in range(n_joints):
        low, high = result.design.ranges[j]
        axes[j, 0].step(result.t, result.u[:, j], where="post", lw=0.8)
        axes[j, 0].axhline(low, color="k", ls=":", lw=0.6)
        axes[j, 0].axhline(high, color="k", ls=":", lw=0.6)
        axes[j, 0].set_ylabel(f"u{j + 1} [rad]")
        axes[j, 1].hist(result.u[:, j], bins=20, range=(low, high))
        freq, psd = scipy.signal.welch(result.u[:, j] - result.u[:, j].mean(), fs=fs, nperseg=min(1024, result.u.shape[0]))
        axes[j, 2].semilogy(freq[1:], np.maximum(psd[1:], 1e-12))
    axes[-1, 0].set_xlabel("t [s]")
    axes[-1, 1].set_xlabel("amplitude [rad]")
    axes[-1, 2].set_xlabel("frequency [Hz]")
    axes[0, 0].set_title("APRBS")
    axes[0, 1].set_title("amplitude histogram")
    axes[0, 2].set_title("power spectral density [rad²/Hz]")
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path, dpi=100)
    return fig
