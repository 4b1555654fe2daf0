"""An on-disk cache of a CasADi function compiled together with its first derivatives.

CasADi's own JIT (``"jit": True, "compiler": "shell"``) compiles a function and each of its
derivatives again in every process: for the excitation design's per-sample information function
this is most of the build. :func:`cached_jit` instead generates the C source of the function, its
forward derivative ``forward(1)`` and its reverse derivative ``reverse(1)`` in one file with
``casadi.CodeGenerator``, compiles it once with the system C compiler into
``<cache>/jit`` (``$ROBOT_OED_CACHE/jit``, by default ``~/.cache/robot-oed/jit``), keyed by a hash of
the function's serialization, the compiler, its flags and the CasADi version, and loads it with
``casadi.external``.

``casadi.external(name, library)`` finds the derivatives by CasADi's default names:
``forward(1)`` of ``name`` is called ``fwd1_<name>`` and ``reverse(1)`` is ``adj1_<name>``
(CasADi's ``External::has_forward``/``has_reverse`` look these symbols up in the library). More
directions (``forward(k)``, ``k > 1``) are built by CasADi from ``fwd1_<name>``.

Every failure (no compiler, a compile or load error, a cache directory that cannot be written)
returns ``None``, so the caller can fall back to CasADi's JIT or to the virtual machine.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import casadi

from dynamics.codegen.compiled import cache_directory, find_compiler

#: the flags of the design's CasADi JIT (``-O1``): the same code, hence the same numbers
JIT_FLAGS: tuple[str, ...] = ("-O1", "-fPIC", "-shared")
#: what a library holds, part of its hash: change it when :func:`derivative_source` changes
GENERATED = "function, forward(1), reverse(1); casadi.CodeGenerator defaults"


@dataclass(frozen=True)
class CachedFunction:
    """A function loaded from the compile cache.

    Attributes
    ----------
    function
        ``casadi.external`` of the library, with ``forward(1)`` and ``reverse(1)`` compiled.
    library
        Path of the shared library in the cache.
    hit
        ``True`` when the library was in the cache already (nothing was compiled).
    """

    function: casadi.Function
    library: Path
    hit: bool


def jit_directory() -> Path:
    """Where :func:`cached_jit` keeps its libraries: ``<cache>/jit`` (see ``dynamics.codegen.compiled``)."""
    return cache_directory() / "jit"


def derivative_source(function: casadi.Function) -> bytes:
    """C source of ``function``, ``function.forward(1)`` and ``function.reverse(1)`` in one file."""
    with tempfile.TemporaryDirectory(prefix="robot-oed-jit-") as work:
        source_name = f"{function.name()}.c"
        generator = casadi.CodeGenerator(source_name)
        for part in (function, function.forward(1), function.reverse(1)):
            generator.add(part)
        generator.generate(work + os.sep)
        return Path(work, source_name).read_bytes()


def library_path(function: casadi.Function, compiler: str, directory: Path) -> Path:
    """The cache entry of ``function``: ``<directory>/<name>_<hash>.so``.

    The hash is over CasADi's serialization of ``function`` (the expression graph, names and
    sparsities, from which the generated source follows), the compiler, :data:`JIT_FLAGS`, the
    CasADi version and :data:`GENERATED`: a hit costs no code generation (~0.05 s for the design).
    """
    parts = (function.serialize(), " ".join((compiler, *JIT_FLAGS)), casadi.__version__, GENERATED)
    fingerprint = "\0".join(parts).encode()
    return directory / f"{function.name()}_{hashlib.sha256(fingerprint).hexdigest()[:16]}.so"


def compile_into(source: bytes, compiler: str, library: Path) -> None:
    """Compile ``source`` into ``library``, atomically: the library is built under a temporary name
    in the same directory and renamed into place, so concurrent processes never load half a file.

    Raises
    ------
    OSError, subprocess.SubprocessError
        When the directory cannot be written or the compiler fails.
    """
    library.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="robot-oed-jit-", dir=library.parent) as work:
        source_path = Path(work, "function.c")
        source_path.write_bytes(source)
        target = Path(work, library.name)
        subprocess.run([compiler, *JIT_FLAGS, "-o", str(target), str(source_path)],
                       check=True, capture_output=True, timeout=600)
        os.replace(target, library)


def cached_jit(function: casadi.Function, directory: Path | None = None) -> CachedFunction | None:
    """``function`` compiled with its first derivatives, from the on-disk cache (built on a miss).

    Parameters
    ----------
    function
        A CasADi function (usually SX) whose derivatives have CasADi's default names.
    directory
        The cache directory; default :func:`jit_directory`.

    Returns
    -------
    CachedFunction or None
        ``None`` when there is no C compiler or anything fails (code generation, compiling,
        writing the cache, loading the library): the caller falls back to its uncached path.
    """
    compiler = find_compiler()
    if compiler is None:
        return None
    try:
        library = library_path(function, compiler, directory or jit_directory())
        hit = library.exists()
        if not hit:
            compile_into(derivative_source(function), compiler, library)
        return CachedFunction(casadi.external(function.name(), str(library)), library, hit)
    except (OSError, RuntimeError, subprocess.SubprocessError):
        return None
