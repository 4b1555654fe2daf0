"""``oed aprbs`` as a library call: an APRBS for the servo arm (:mod:`oed.aprbs_signal`), written as ``t, u1..uJ``
[rad] to CSV by :meth:`AprbsRun.write`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dynamics.robots.servo_arm import SERVO_ARM_RANGES
from dynamics.runtime.output_files import OutputFiles
from estimation.servo.files import write_csv
from oed.aprbs_signal import APRBSDesign, design_aprbs

__all__ = ["AprbsRun", "aprbs"]


@dataclass(frozen=True)
class AprbsRun:
    """The designed signal (``result``: :class:`oed.aprbs_signal.APRBSResult`) of ``joints`` joints."""

    result: Any = field(repr=False)
    joints: int

    def columns(self) -> dict[str, Any]:
        """The CSV's columns ``t, u1..uJ``."""
        return {"t": self.result.t, **{f"u{j + 1}": self.result.u[:, j] for j in range(self.joints)}}

    def summary(self) -> list[str]:
        """The line ``oed aprbs`` prints after ``wrote OUT: ``."""
        scores = self.result.candidate_scores
        return [f"{self.result.t.size} samples x {self.joints} joints, criterion {self.result.score:.4f} "
                f"(best of {len(scores)}, worst {min(scores):.4f})"]

    def plot(self, path: str | Path) -> None:
        """The signal, histogram and spectrum figure at ``path``."""
        from oed.aprbs_figures import plot_aprbs

        plot_aprbs(self.result, path)

    def write(self, out: str | Path, *, figure: str | Path | None = None) -> None:
        """The CSV at ``out`` and, with ``figure``, the figure: both or neither."""
        with OutputFiles() as outputs:
            write_csv(outputs.stage(out), self.columns())
            if figure:
                self.plot(outputs.stage_figure(figure))


def aprbs(*, joints: int = 4, duration: float = 60.0, dt: float = 0.01, hold_min: float = 0.2,
          hold_max: float | None = None, levels: int = 12, candidates: int = 64, seed: int | None = None) -> AprbsRun:
    """``oed aprbs``: the best of ``candidates`` random APRBS of the servo arm's first ``joints`` joints (the
    paper's ranges)."""
    if not 1 <= joints <= len(SERVO_ARM_RANGES):
        raise ValueError(f"--joints must be between 1 and {len(SERVO_ARM_RANGES)}, got {joints}")
    design = APRBSDesign(ranges=SERVO_ARM_RANGES[:joints], duration=duration, dt=dt, hold_min=hold_min,
                         hold_max=hold_max, n_levels=levels)
    return AprbsRun(design_aprbs(design, candidates=candidates, seed=seed), joints)
