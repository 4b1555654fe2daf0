"""Fast evaluation of CasADi functions over many samples.

Two costs dominate a mapped evaluation from Python (measured in ``benchmarks/bench_regressor.py``):
the CasADi virtual machine (~10 µs a sample for a 6-joint regressor) and the conversion of the
result between ``casadi.DM`` and numpy (~60–70 ns an element, more than the evaluation itself).
This module removes both:

- :func:`compile_function` generates C code for a function, compiles it once with the system C
  compiler into an on-disk cache (``$ROBOT_OED_CACHE`` or ``~/.cache/robot-oed``, keyed by a hash
  of the source, the compiler, its flags and the CasADi version) and loads it with
  ``casadi.external``. Without a compiler, or when compilation fails, the function is returned
  unchanged (virtual machine).
- :class:`SampleEvaluator` evaluates a per-sample function over ``N`` samples, reading the inputs
  from and writing the output into numpy arrays without copies. Compiled, it calls a small C loop
  appended to the generated code (``<name>_samples``) through ``ctypes``: CasADi's ``map`` over an
  external function locks a mutex and checks sparsities at every sample, which cost as much as
  the 3-joint regressor itself (0.19 against 0.08 µs a sample). Without a compiler it uses ``map``
  and CasADi's buffer interface.

``ROBOT_OED_BACKEND=vm`` disables compilation (for comparison, or where no compiler may run).
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Literal

import casadi
import numpy as np
from numpy.typing import NDArray

from dynamics.runtime.threads import sample_thread_limit

Backend = Literal["auto", "vm", "compiled"]
# Portable flags only (no -march=native: the cache may be shared between machines, and it gains
# nothing measurable here). Hidden visibility lets the compiler inline CasADi's helpers such as
# casadi_sq instead of calling them through the PLT (-8 % on the 3-joint regressor); the macro makes
# CasADi mark its entry points visible again. -ffast-math is left out: it would let NaN and inf
# through unchecked and reorder sums.
COMPILER_FLAGS: tuple[str, ...] = ("-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-DGCC_HASCLASSVISIBILITY")

_SAMPLE_LOOP = """
/* robot-oed: evaluate {name} over n samples stored row after row, without CasADi's per-call costs */
#include <stdlib.h>
CASADI_SYMBOL_EXPORT int {name}_samples(long long n, const casadi_real** inputs, casadi_real* output) {{
  const casadi_real* arg[{sz_arg}];
  casadi_real* res[{sz_res}];
  static const long long width[{n_in}] = {{{widths}}};
  casadi_int* iw = (casadi_int*) malloc(sizeof(casadi_int) * {sz_iw});
  casadi_real* w = (casadi_real*) malloc(sizeof(casadi_real) * {sz_w});
  long long sample;
  int i, mem, flag = 0;
  if (!iw || !w) {{ free(iw); free(w); return -1; }}
  for (i = 0; i < {sz_arg}; ++i) arg[i] = 0;
  for (i = 0; i < {sz_res}; ++i) res[i] = 0;
  mem = {name}_checkout();
  for (sample = 0; sample < n && !flag; ++sample) {{
    for (i = 0; i < {n_in}; ++i) arg[i] = inputs[i] + sample * width[i];
    res[0] = output + sample * {nnz_out};
    flag = {name}(arg, res, iw, w, mem);
  }}
  {name}_release(mem);
  free(iw);
  free(w);
  return flag;
}}
"""


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
    library = compile_library(function, backend)
    return function if library is None else casadi.external(function.name(), str(library))


@functools.lru_cache(maxsize=128)
def compile_library(function: casadi.Function, backend: Backend = "auto") -> Path | None:
    """The shared library of ``function`` (built once, cached on disk), or ``None`` for the VM.

    Besides CasADi's entry points it exports ``<name>_samples(n, inputs, output)``, the loop over
    ``n`` samples that :class:`SampleEvaluator` calls. Arguments as for :func:`compile_function`.
    """
    if backend == "vm":
        return None
    compiler = find_compiler()
    if compiler is None:
        if backend == "compiled":
            raise RuntimeError("no C compiler found (set CC) for backend='compiled'")
        return None
    source = generated_source(function) + _sample_loop(function).encode()
    fingerprint = source + " ".join((compiler, *COMPILER_FLAGS)).encode() + casadi.__version__.encode()
    key = hashlib.sha256(fingerprint).hexdigest()[:16]
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
            return None
    return library


#: what ``casadi.CodeGenerator.generate`` writes around the code ``dump`` returns (CodeGenerator::file_open and
#: file_close in CasADi's code_generator.cpp)
_GENERATED_HEAD = ("/* This file was automatically generated by CasADi {version}.\n"
                   " *  It consists of: \n"
                   " *   1) content generated by CasADi runtime: not copyrighted\n"
                   " *   2) template code copied from CasADi source: permissively licensed (MIT-0)\n"
                   " *   3) user code: owned by the user\n"
                   " *\n"
                   " */\n"
                   "#ifdef __cplusplus\n"
                   "extern \"C\" {{\n"
                   "#endif\n\n")
_GENERATED_TAIL = "#ifdef __cplusplus\n} /* extern \"C\" */\n#endif\n"


def generated_source(function: casadi.Function) -> bytes:
    """The C source ``casadi.CodeGenerator(NAME.c).generate()`` writes for ``function``, made in memory: the
    cache key of a library is computed at every first use of a function in a process, and a temporary directory
    for the file (created, written, read, removed) cost more than the code generation itself (0.4 s of
    ``oed diagnose`` on a 7-joint log, 160 functions)."""
    generator = casadi.CodeGenerator(f"{function.name()}.c")
    generator.add(function)
    return (_GENERATED_HEAD.format(version=casadi.__version__) + generator.dump() + _GENERATED_TAIL).encode()


def _sample_loop(function: casadi.Function) -> str:
    """C source of ``<name>_samples``, the loop over samples appended to the generated code."""
    return _SAMPLE_LOOP.format(
        name=function.name(),
        sz_arg=max(1, function.sz_arg()),
        sz_res=max(1, function.sz_res()),
        sz_iw=max(1, function.sz_iw()),
        sz_w=max(1, function.sz_w()),
        n_in=max(1, function.n_in()),
        widths=", ".join(str(function.nnz_in(index)) for index in range(function.n_in())) or "0",
        nnz_out=function.nnz_out(0) if function.n_out() else 0,
    )


@functools.lru_cache(maxsize=128)
def _sample_loop_entry(library: Path, name: str) -> ctypes._CFuncPtr:
    entry = getattr(ctypes.CDLL(str(library)), f"{name}_samples")
    entry.argtypes = [ctypes.c_longlong, ctypes.POINTER(ctypes.c_void_p), ctypes.c_void_p]
    entry.restype = ctypes.c_int
    return entry


class SampleEvaluator:
    """Evaluate a per-sample function ``(x1, …, xk) -> out`` over ``N`` samples, numpy in and out.

    Inputs are ``(N, len_i)`` arrays (one row a sample); the output is ``(N, out.numel())`` with
    each row the per-sample output in column-major order (a sparse output is scattered into
    place).

    Parameters
    ----------
    function
        Per-sample function with dense inputs and one output.
    backend
        See :func:`compile_function` (default: ``$ROBOT_OED_BACKEND`` or ``auto``).
    threads
        Split the samples over up to that many threads (the C loop frees the GIL).
    min_samples_per_thread
        Fewer samples run on fewer threads. Default: enough for about ``WORK_PER_THREAD``
        CasADi instructions a thread (about 0.4 ms), and at least ``MIN_SAMPLES_PER_THREAD``;
        below that, starting a thread costs more than it saves.
    """

    MIN_SAMPLES_PER_THREAD = 500
    WORK_PER_THREAD = 2_000_000

    def __init__(
        self,
        function: casadi.Function,
        *,
        backend: Backend | None = None,
        threads: int = 1,
        min_samples_per_thread: int | None = None,
    ) -> None:
        if not isinstance(threads, int) or threads < 1:
            raise ValueError(f"threads must be a positive integer, got {threads!r}")
        self.threads = threads
        if min_samples_per_thread is None:
            per_sample = max(1, function.n_instructions())
            min_samples_per_thread = max(self.MIN_SAMPLES_PER_THREAD, -(-self.WORK_PER_THREAD // per_sample))
        self.min_samples_per_thread = max(1, int(min_samples_per_thread))
        for index in range(function.n_in()):
            if not function.sparsity_in(index).is_dense():
                raise ValueError(f"input {function.name_in(index)} of {function.name()} must be dense")
        self.function = function
        self.backend: Backend = backend or default_backend()
        # CasADi's Python calls cost about a microsecond each: ask once, not at every call
        self._widths = tuple(function.nnz_in(index) for index in range(function.n_in()))
        self._numel_out, self._nnz_out = function.numel_out(0), function.nnz_out(0)
        sparsity = function.sparsity_out(0)
        rows, columns = sparsity.get_triplet()
        # where each nonzero goes in the column-major flattening; None for a dense output
        self._scatter = None if sparsity.is_dense() else np.asarray(columns) * sparsity.size1() + np.asarray(rows)
        self._compiled: casadi.Function | None = None
        self._loop: ctypes._CFuncPtr | None | bool = False  # False: not looked up yet

    def __getstate__(self) -> dict[str, object]:
        # the loaded library (ctypes) and CasADi's external do not pickle: load them again lazily
        return {**self.__dict__, "_compiled": None, "_loop": False}

    @property
    def compiled(self) -> casadi.Function:
        """The function as CasADi calls it: compiled (``casadi.external``) or the original (VM)."""
        if self._compiled is None:
            self._compiled = compile_function(self.function, self.backend)
        return self._compiled

    @property
    def sample_loop(self) -> ctypes._CFuncPtr | None:
        """The compiled ``<name>_samples`` C loop, or ``None`` when running on the VM."""
        if self._loop is False:
            library = compile_library(self.function, self.backend)
            self._loop = None if library is None else _sample_loop_entry(library, self.function.name())
        return self._loop  # type: ignore[return-value]

    def __call__(self, *inputs: NDArray[np.float64], out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """The output ``(N, out.numel())`` at the ``N`` samples; ``out``: write into this array instead
        (float64, C-contiguous, ``N·numel`` elements in any shape) and return it reshaped."""
        if len(inputs) != len(self._widths):
            raise ValueError(f"{self.function.name()} takes {len(self._widths)} inputs, got {len(inputs)}")
        n_samples = inputs[0].shape[0]
        arrays = []
        for index, (values, expected) in enumerate(zip(inputs, self._widths)):
            values = np.ascontiguousarray(values, dtype=float)
            if values.shape[0] != n_samples or values.size != n_samples * expected:
                raise ValueError(
                    f"input {self.function.name_in(index)} must be ({n_samples}, {expected}), got {values.shape}"
                )
            arrays.append(values)
        if out is None:
            output = np.empty((n_samples, self._numel_out))
        else:
            output = _output_view(out, n_samples, self._numel_out)
        if self._scatter is None:  # a dense output is written whole by the function: no need to zero it
            target = output
        else:
            output[...] = 0.0
            target = np.empty((n_samples, self._nnz_out))
        threads = min(self.threads, sample_thread_limit() or self.threads)
        loop = self.sample_loop
        if loop is not None:
            self._run_loop(loop, arrays, target, threads)
        elif n_samples:
            buffer, trigger = _mapped(self.compiled, n_samples, threads).buffer()
            for index, values in enumerate(arrays):
                buffer.set_arg(index, memoryview(values))
            buffer.set_res(0, memoryview(target))
            trigger()
        if self._scatter is not None:
            output[:, self._scatter] = target
        return output

    def _run_loop(self, loop: ctypes._CFuncPtr, arrays: list[NDArray[np.float64]], target: NDArray[np.float64],
                  threads: int) -> None:
        """Run the C loop over the samples, in ``threads`` slices at most (ctypes frees the GIL;
        :func:`dynamics.runtime.threads.single_threaded` lowers the limit to one)."""
        n_samples = target.shape[0]
        n_slices = max(1, min(threads, n_samples // self.min_samples_per_thread))
        bounds = [n_samples * part // n_slices for part in range(n_slices + 1)]

        def run(start: int, stop: int) -> int:
            pointers = (ctypes.c_void_p * max(1, len(arrays)))(*(values[start:].ctypes.data for values in arrays))
            return loop(stop - start, pointers, target[start:].ctypes.data)

        if n_slices == 1:
            flags = [run(0, n_samples)] if n_samples else []
        else:
            pool = _pool(n_slices - 1, os.getpid())
            pending = [pool.submit(run, start, stop) for start, stop in zip(bounds[1:-1], bounds[2:])]
            flags = [run(bounds[0], bounds[1])] + [job.result() for job in pending]
        if any(flags):
            raise RuntimeError(f"{self.function.name()} failed on some samples (flag {max(flags, key=abs)})")


def _output_view(out: NDArray[np.float64], n_samples: int, width: int) -> NDArray[np.float64]:
    """``out`` as an ``(n_samples, width)`` view, or a ``TypeError``/``ValueError`` saying why not."""
    if not isinstance(out, np.ndarray) or out.dtype != np.float64:
        raise TypeError(f"out must be a float64 numpy array, got {getattr(out, 'dtype', type(out).__name__)}")
    if not out.flags.c_contiguous or not out.flags.writeable:
        raise ValueError("out must be C-contiguous and writeable")
    if out.size != n_samples * width:
        raise ValueError(f"out has {out.size} elements; {n_samples} samples need {n_samples * width}")
    return out.reshape(n_samples, width)


@functools.lru_cache(maxsize=8)
def _pool(workers: int, process: int) -> ThreadPoolExecutor:
    """Worker threads, one pool per process id: a forked child (ProcessPoolExecutor) inherits
    the parent's pool object without its threads, and would wait for them forever."""
    return ThreadPoolExecutor(max_workers=workers, thread_name_prefix="robot-oed-samples")


@functools.lru_cache(maxsize=64)
def _mapped(function: casadi.Function, n_samples: int, threads: int = 1) -> casadi.Function:
    if threads == 1:
        return function.map(n_samples)
    return function.map(n_samples, "thread", threads)
