"""The sums of a least-squares Fourier fit: its normal equations and its fitted values, without its design.

A Fourier series of ``H`` harmonics of ``f`` over ``N`` samples has the design ``[1, sin kθ_n, cos kθ_n]``
(``θ_n = 2π f (t_n − t_origin)``, ``k = 1 … H``): ``N × (2H + 1)``. Forming it and its Gram matrix costs
``O(N H²)``, seconds for a 14 000-sample record at 1 000 harmonics. Two ways to the same sums:

* :class:`UniformFourierSums`, time stamps on a regular grid ``θ_n = θ_0 + n φ``: with the power sums
  ``p_d = Σ_n e^{i d θ_n}`` (``d = 0 … 2H``) the normal matrix is, for ``j, k ≥ 1``,

      Σ cos jθ cos kθ = ½ Re(p_{|j−k|} + p_{j+k}),     Σ sin jθ sin kθ = ½ Re(p_{|j−k|} − p_{j+k}),
      Σ sin jθ cos kθ = ½ (Im p_{j+k} + Im p_{j−k}),   Σ cos kθ = Re p_k,   Σ sin kθ = Im p_k,

  with ``p_{−d} = conj p_d``; the moments are ``Σ_n y_n e^{−ikθ_n}`` and the fitted values ``Re Σ_k x_k
  e^{ikθ_n}``. Each is a chirp z-transform (Rabiner, Schafer & Rader, "The chirp z-transform algorithm", IEEE
  Trans. Audio Electroacoust. 17, 1969; :func:`chirp_sums`), ``O((N + H) log(N + H))``.
* :class:`BlockFourierSums`, any time stamps: the design formed over blocks of rows, ``O(N H²)``.

Both give the same numbers to rounding (``tests/test_noise_floor.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft
from numpy.typing import NDArray

#: time stamps within this fraction of a step of a regular grid are on it (a phase error below 1e-9 of a step)
GRID_TOLERANCE = 1e-9
#: rows of the design formed at once by :class:`BlockFourierSums`
BLOCK_ROWS = 4096


@dataclass(frozen=True)
class BlockFourierSums:
    """The Fourier fit's sums over blocks of rows of its design (any time stamps)."""

    t: NDArray[np.float64]
    frequency_hz: float
    harmonics: int
    origin: float

    def design(self, rows: slice) -> NDArray[np.float64]:
        """Rows ``rows`` of the design ``[1, sin kθ, cos kθ]``."""
        omega = 2 * np.pi * self.frequency_hz * np.arange(1, self.harmonics + 1)
        phase = np.outer(self.t[rows] - self.origin, omega)
        return np.hstack([np.ones((phase.shape[0], 1)), np.sin(phase), np.cos(phase)])

    def blocks(self) -> list[slice]:
        return [slice(start, start + BLOCK_ROWS) for start in range(0, self.t.shape[0], BLOCK_ROWS)]

    def normal_equations(self, values: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(AᵀA, Aᵀ values)`` of the design ``A`` and ``values (N, m)``."""
        k = 2 * self.harmonics + 1
        normal, moment = np.zeros((k, k)), np.zeros((k, values.shape[1]))
        for rows in self.blocks():
            A = self.design(rows)
            normal += A.T @ A
            moment += A.T @ values[rows]
        return normal, moment

    def fitted(self, coefficients: NDArray[np.float64]) -> NDArray[np.float64]:
        """``A · coefficients``, ``(N, m)`` for ``coefficients (2H + 1, m)``."""
        return np.vstack([self.design(rows) @ coefficients for rows in self.blocks()])


def fractional_turns(rate: float, counts: NDArray[np.float64]) -> NDArray[np.float64]:
    """``rate · counts`` modulo 1, to the rounding of the result, for exact ``counts`` (whole or half numbers below
    2³³): ``rate`` is split into a 20-bit head, whose products are exact, and the rest (Dekker's splitting). A
    phase of ``10⁵`` turns keeps ``1e-16`` turns of error, where ``rate · counts`` rounded would keep ``1e-11``."""
    mantissa, exponent = np.frexp(rate)
    head = float(np.ldexp(np.trunc(np.ldexp(mantissa, 20)), exponent - 20))
    whole = head * counts  # exact
    rest = (rate - head) * counts
    turns = (whole - np.floor(whole)) + (rest - np.floor(rest))
    return turns - np.floor(turns)


def chirp_sums(values: NDArray[np.complex128] | NDArray[np.float64], count: int,
               rate: float) -> NDArray[np.complex128]:
    """``X_k = Σ_n x_n e^{2πi ν n k}``, ``k = 0 … count − 1``, of ``values (N, m)`` and ``ν = rate`` turns, by
    Bluestein's convolution (``nk = (n² + k² − (k − n)²) / 2``) with the chirp's phases reduced exactly
    (:func:`fractional_turns`): what ``scipy.signal.czt`` computes, with its phase error at ``10⁵`` turns removed."""
    n_values = values.shape[0]
    length = scipy.fft.next_fast_len(n_values + count - 1)
    lags = np.arange(-(n_values - 1), count, dtype=float)
    chirp = np.exp(2j * np.pi * fractional_turns(rate, 0.5 * lags**2))  # e^{iπν j²}, j = −(N−1) … count−1
    kernel = np.zeros(length, dtype=complex)
    kernel[:count] = np.conj(chirp[n_values - 1:])
    kernel[length - n_values + 1:] = np.conj(chirp[:n_values - 1])
    weighted = values * chirp[n_values - 1:2 * n_values - 1, None] if n_values <= count else \
        values * np.exp(2j * np.pi * fractional_turns(rate, 0.5 * np.arange(n_values, dtype=float) ** 2))[:, None]
    convolved = scipy.fft.ifft(scipy.fft.fft(weighted, length, axis=0) * scipy.fft.fft(kernel)[:, None], axis=0)
    return convolved[:count] * chirp[n_values - 1:, None]


@dataclass(frozen=True)
class UniformFourierSums:
    """The Fourier fit's sums on a regular grid, ``θ_n = 2π (τ + n ν)`` (``τ`` turns at the first sample, ``ν``
    turns a sample), each a chirp z-transform (module docstring, :func:`chirp_sums`)."""

    turns_at_start: float
    turns_per_sample: float
    n_samples: int
    harmonics: int

    @classmethod
    def of(cls, t: NDArray[np.float64], frequency_hz: float, harmonics: int,
           origin: float) -> UniformFourierSums | None:
        """The sums of time stamps ``t`` when they lie on a regular grid (to :data:`GRID_TOLERANCE` of a step),
        else ``None``; phases from ``origin``."""
        t = np.asarray(t, dtype=float).reshape(-1)
        if t.shape[0] < 2:
            return None
        step = (t[-1] - t[0]) / (t.shape[0] - 1)
        if not step > 0 or np.max(np.abs(t - (t[0] + step * np.arange(t.shape[0])))) > GRID_TOLERANCE * step:
            return None
        return cls(frequency_hz * (t[0] - origin), frequency_hz * step, t.shape[0], int(harmonics))

    def rotation(self, count: int, sign: float = 1.0) -> NDArray[np.complex128]:
        """``e^{± 2πi k τ}``, ``k = 0 … count − 1``: the phase of each harmonic at the first sample."""
        return np.exp(sign * 2j * np.pi * fractional_turns(self.turns_at_start, np.arange(count, dtype=float)))

    def power_sums(self) -> NDArray[np.complex128]:
        """``p_d = Σ_n e^{i d θ_n}``, ``d = 0 … 2H``."""
        count = 2 * self.harmonics + 1
        return self.rotation(count) * chirp_sums(np.ones((self.n_samples, 1)), count, self.turns_per_sample)[:, 0]

    def normal_equations(self, values: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(AᵀA, Aᵀ values)`` of the design ``A = [1, sin kθ, cos kθ]`` and ``values (N, m)``."""
        H = self.harmonics
        power = self.power_sums()
        k = np.arange(1, H + 1)
        difference, total = np.abs(k[:, None] - k[None, :]), k[:, None] + k[None, :]
        sign = np.sign(k[:, None] - k[None, :])
        normal = np.empty((2 * H + 1, 2 * H + 1))
        normal[0, 0] = self.n_samples
        normal[0, 1:H + 1] = normal[1:H + 1, 0] = power[k].imag
        normal[0, H + 1:] = normal[H + 1:, 0] = power[k].real
        normal[1:H + 1, 1:H + 1] = 0.5 * (power[difference].real - power[total].real)
        normal[H + 1:, H + 1:] = 0.5 * (power[difference].real + power[total].real)
        normal[1:H + 1, H + 1:] = 0.5 * (power[total].imag + sign * power[difference].imag)  # sin j, cos k
        normal[H + 1:, 1:H + 1] = normal[1:H + 1, H + 1:].T
        transform = self.rotation(H + 1, -1.0)[:, None] * chirp_sums(values, H + 1, -self.turns_per_sample)
        moment = np.vstack([transform[:1].real, -transform[1:].imag, transform[1:].real])
        return normal, moment

    def fitted(self, coefficients: NDArray[np.float64]) -> NDArray[np.float64]:
        """``A · coefficients``, ``(N, m)`` for ``coefficients (2H + 1, m)`` of ``[1, sin kθ, cos kθ]``."""
        H = self.harmonics
        series = np.zeros((H + 1, coefficients.shape[1]), dtype=complex)
        series[1:] = (coefficients[H + 1:] - 1j * coefficients[1:H + 1]) * self.rotation(H + 1)[1:, None]
        return coefficients[0] + chirp_sums(series, self.n_samples, self.turns_per_sample).real


def fourier_sums(t: NDArray[np.float64], frequency_hz: float, harmonics: int,
                 origin: float) -> UniformFourierSums | BlockFourierSums:
    """The cheapest sums for time stamps ``t``: chirp z-transforms on a regular grid, blocks of the design else."""
    t = np.asarray(t, dtype=float).reshape(-1)
    return UniformFourierSums.of(t, frequency_hz, harmonics, origin) or \
        BlockFourierSums(t, float(frequency_hz), int(harmonics), float(origin))
