"""Fast evaluation of CasADi functions over many samples.

Two costs dominate a mapped evaluation from Python (measured in ``benchmarks/bench_regressor.py``):
the CasADi virtual machine (~10 µs a sample for a 6-joint regressor) and the conversion of the
result between ``casadi.DM`` and numpy (~60–70 ns an element, more than the evaluation itself).
This module removes both:

- :func:`compile_function` generates C code for a function, compiles it once with the system C
  compiler into an on-disk cache (``$ROBOT_OED_CACHE`` or ``~/.cache/robot-oed``, keyed by a hash
  of the source, the flags and the CasADi version) and loads it with ``casadi.external``. Without
  a compiler, or when compilation fails, the function is returned unchanged (virtual machine).
- :class:`SampleEvaluator` evaluates a per-sample function over ``N`` samples with ``map`` and
  CasADi's buffer interface, reading the inputs from and writing the output into numpy arrays
  without copies.

``ROBOT_OED_BACKEND=vm`` disables compilation (for comparison, or where no compiler may run).
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path
from typing import Literal

import casadi
import numpy as np
from numpy.typing import NDArray

Backend = Literal["auto", "vm", "compiled"]
COMPILER_FLAGS: tuple[str, ...] = ("-O2", "-fPIC", "-shared")


def cache_directory() -> Path:
    """Where compiled functions are kept."""
    return Path(os.environ.get("ROBOT_OED_CACHE", Path.home() / ".cache" / "robot-oed"))


def default_backend() -> Backend:
    value = os.environ.get("ROBOT_OED_BACKEND", "auto").lower()
    if value not in ("auto", "vm", "compiled"):
        raise ValueError(f"ROBOT_OED_BACKEND must be auto, vm or compiled, got {value!r}")
    return value  # type: ignore[return-value]


def find_compiler() -> str | None:
    """The C compiler to use (``$CC``, ``cc``, ``gcc`` or ``clang``), or ``None``."""
    for candidate in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if candidate and shutil.which(candidate):
            return candidate
    return None


@functools.lru_cache(maxsize=128)
def compile_function(function: casadi.Function, backend: Backend = "auto") -> casadi.Function:
    """``function`` as compiled C code (cached on disk), or itself when compiling is off or fails.

    Parameters
    ----------
    function
        Any CasADi function (SX or MX).
    backend
        ``auto``: compile if a C compiler exists, else fall back with a warning-free VM;
        ``vm``: never compile; ``compiled``: compile or raise ``RuntimeError``.
    """
    if backend == "vm":
        return function
    compiler = find_compiler()
    if compiler is None:
        if backend == "compiled":
            raise RuntimeError("no C compiler found (set CC) for backend='compiled'")
        return function
    with tempfile.TemporaryDirectory(prefix="robot-oed-") as work:
        source_name = f"{function.name()}.c"
        generator = casadi.CodeGenerator(source_name)
        generator.add(function)
        generator.generate(work + os.sep)
        source = Path(work, source_name).read_bytes()
    key = hashlib.sha256(source + " ".join(COMPILER_FLAGS).encode() + casadi.__version__.encode()).hexdigest()[:16]
    directory = cache_directory()
    library = directory / f"{function.name()}_{key}.so"
    if not library.exists():
        try:
            directory.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(prefix="robot-oed-", dir=directory) as work:
                source_path = Path(work, "function.c")
                source_path.write_bytes(source)
                target = Path(work, library.name)
                subprocess.run(
                    [compiler, *COMPILER_FLAGS, "-o", str(target), str(source_path)],
                    check=True, capture_output=True, timeout=600,
                )
                os.replace(target, library)  # atomic: concurrent builders never see half a library
        except (OSError, subprocess.SubprocessError) as error:
            if backend == "compiled":
                raise RuntimeError(f"compiling {function.name()} failed: {error}") from None
            warnings.warn(f"compiling {function.name()} failed ({error}); using the CasADi virtual machine", RuntimeWarning, stacklevel=2)
            return function
    return casadi.external(function.name(), str(library))


class SampleEvaluator:
    """Evaluate a per-sample function ``(x1, …, xk) -> out`` over ``N`` samples, numpy in and out.

    Inputs are ``(N, len_i)`` arrays (one row a sample); the output is ``(N, out.numel())`` with
    each row the per-sample output in column-major order (a sparse output is scattered into
    place). ``threads > 1`` splits the samples over that many threads (``map(N, "thread", k)``).
    """

    def __init__(self, function: casadi.Function, *, backend: Backend | None = None, threads: int = 1) -> None:
        if not isinstance(threads, int) or threads < 1:
            raise ValueError(f"threads must be a positive integer, got {threads!r}")
        self.threads = threads
        for index in range(function.n_in()):
            if not function.sparsity_in(index).is_dense():
                raise ValueError(f"input {function.name_in(index)} of {function.name()} must be dense")
        self.function = function
        self.backend: Backend = backend or default_backend()
        self._compiled: casadi.Function | None = None

    @property
    def compiled(self) -> casadi.Function:
        if self._compiled is None:
            self._compiled = compile_function(self.function, self.backend)
        return self._compiled

    def __call__(self, *inputs: NDArray[np.float64]) -> NDArray[np.float64]:
        if len(inputs) != self.function.n_in():
            raise ValueError(f"{self.function.name()} takes {self.function.n_in()} inputs, got {len(inputs)}")
        n_samples = inputs[0].shape[0]
        arrays = []
        for index, values in enumerate(inputs):
            values = np.ascontiguousarray(values, dtype=float)
            expected = self.function.nnz_in(index)
            if values.shape[0] != n_samples or values.reshape(n_samples, -1).shape[1] != expected:
                raise ValueError(
                    f"input {self.function.name_in(index)} must be ({n_samples}, {expected}), got {values.shape}"
                )
            arrays.append(values)
        dense_output = self.function.sparsity_out(0).is_dense()
        # a dense output is written whole by the function: no need to zero it first
        output = (np.empty if dense_output else np.zeros)((n_samples, self.function.numel_out(0)))
        target = output if dense_output else np.empty((n_samples, self.function.nnz_out(0)))
        buffer, trigger = _mapped(self.compiled, n_samples, self.threads).buffer()
        for index, values in enumerate(arrays):
            buffer.set_arg(index, memoryview(values))
        buffer.set_res(0, memoryview(target))
        trigger()
        if not dense_output:
            sparsity = self.function.sparsity_out(0)
            rows, columns = sparsity.get_triplet()
            output[:, np.asarray(columns) * sparsity.size1() + np.asarray(rows)] = target
        return output


@functools.lru_cache(maxsize=64)
def _mapped(function: casadi.Function, n_samples: int, threads: int = 1) -> casadi.Function:
    if threads == 1:
        return function.map(n_samples)
    return function.map(n_samples, "thread", threads)
