"""Benchmark: the clipped-sensor rule (:func:`estimation.data.log_cleaning.saturated_samples`) on quantised torques
whose smooth peaks are held long, and on the same torques clipped, with the quantised-peak rule
(:func:`estimation.data.log_cleaning.quantised_peak`) and without it (the frequency rule alone, as before
h-streammask).

Two sweeps of 300 draws each (seeded): a torque ``a (sin(2π f t + φ) + b sin(2π 2.3 f t + φ'))`` rounded to a
quantum ``δ``, with white noise of 0 to 2 quanta before the rounding, and the same torque clipped ``c`` quanta below
its peak; the joint moves throughout.

- ``fast``: rates 250–2000 Hz, ``f`` 0.1–2 Hz, ``δ`` 0.1–1 % of ``a``, noise 0, 0.2, 0.45 or 2 quanta, the clip
  2–30 % of the spread below the peak;
- ``slow``: rates 500–2000 Hz, ``f`` 0.1–0.6 Hz, ``δ`` 0.3–2 % of ``a``, noise 0, 0.1 or 0.3 quanta, the clip 1–30
  quanta below the peak (the peaks held longest, the shallow clips).

Per sweep and rule: the quantised records read as clipped (any sample), the clipped records whose clipped samples
are found exactly, missed entirely, or in part. Run: ``python benchmarks/bench_quantised_peaks.py`` (about a
minute).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

import estimation.data.log_cleaning as log_cleaning

DRAWS = 300


def draws(sweep: str) -> Iterator[tuple[np.ndarray, np.ndarray, float, np.ndarray]]:
    """``(quantised, clipped, limit, q)`` of each draw of ``sweep``."""
    generator = np.random.default_rng(0 if sweep == "fast" else 1)
    for _ in range(DRAWS):
        if sweep == "fast":
            rate, frequency = generator.choice([250.0, 500.0, 1000.0, 2000.0]), generator.uniform(0.1, 2.0)
            amplitude = generator.uniform(0.5, 50)
            quantum = amplitude * generator.choice([1e-3, 3e-3, 1e-2])
            t = np.arange(int(rate * generator.uniform(3, 10))) / rate
            signal = amplitude * (np.sin(2 * np.pi * frequency * t + generator.uniform(0, 6))
                                  + 0.3 * np.sin(2 * np.pi * 2.3 * frequency * t))
            noise = generator.choice([0.0, 0.2, 0.45, 2.0]) * quantum
        else:
            rate, frequency = generator.choice([500.0, 1000.0, 2000.0]), generator.uniform(0.1, 0.6)
            amplitude = generator.uniform(0.5, 50)
            quantum = amplitude * generator.choice([3e-3, 1e-2, 2e-2])
            t = np.arange(int(rate * generator.uniform(3, 8))) / rate
            signal = amplitude * (np.sin(2 * np.pi * frequency * t + generator.uniform(0, 6))
                                  + 0.2 * np.sin(2 * np.pi * 2.3 * frequency * t + generator.uniform(0, 6)))
            noise = generator.choice([0.0, 0.1, 0.3]) * quantum
        q = np.sin(2 * np.pi * 0.3 * t)[:, None]
        quantised = quantum * np.round((signal + noise * generator.standard_normal(t.size)) / quantum)
        if sweep == "fast":
            depth = generator.uniform(0.02, 0.3) * np.ptp(signal) / 2
        else:
            depth = generator.uniform(1, 30) * quantum
        limit = quantum * np.round((signal.max() - depth) / quantum)
        yield quantised, np.minimum(quantised, limit), limit, q


def judged(sweep: str) -> dict[str, int]:
    counts = {"quantised read as clipped": 0, "clips exact": 0, "clips missed": 0, "clips in part": 0}
    for quantised, clipped, limit, q in draws(sweep):
        counts["quantised read as clipped"] += bool(log_cleaning.saturated_samples(quantised[:, None], q).any())
        found = log_cleaning.saturated_samples(clipped[:, None], q)[:, 0]
        key = ("clips exact" if np.array_equal(found, clipped == limit)
               else "clips missed" if not found.any() else "clips in part")
        counts[key] += 1
    return counts


def main() -> None:
    rule = log_cleaning.quantised_peak
    for sweep in ("fast", "slow"):
        for label, peak in (("frequency rule alone", lambda *arguments: False), ("with quantised_peak", rule)):
            log_cleaning.quantised_peak = peak
            try:
                print(f"{sweep:>4} sweep, {label:>20}: {judged(sweep)} (of {DRAWS})")
            finally:
                log_cleaning.quantised_peak = rule


if __name__ == "__main__":
    main()
