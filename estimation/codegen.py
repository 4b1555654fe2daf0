"""Compile a ``casadi.Function`` to C once and load it back with ``casadi.external``.

The shared library is cached in ``$ROBOT_OED_CACHE`` (default ``~/.cache/robot-oed``) under a name keyed by
a hash of the generated source, so a rebuilt but identical graph is never recompiled. Without a C compiler
(or if compilation fails) the original function is returned and evaluated by CasADi's virtual machine.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path

import casadi


def cache_directory() -> Path:
    """Folder of the compiled libraries (created on demand)."""
    return Path(os.environ.get("ROBOT_OED_CACHE", Path.home() / ".cache" / "robot-oed"))


def compile_function(function: casadi.Function, *, compiler: str | None = None, flags: tuple[str, ...] = ("-O3",)) -> casadi.Function:
    """Return ``function`` compiled to a shared library, or ``function`` itself when no compiler is available.

    Parameters
    ----------
    function
        Any CasADi function (SX or MX, including ``map``/``mapaccum`` compositions).
    compiler
        C compiler executable; default ``$CC`` or ``gcc``/``cc`` found on ``PATH``.
    flags
        Optimisation flags.
    """
    compiler = compiler or os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if compiler is None:
        warnings.warn(f"no C compiler found: {function.name()} runs in the CasADi virtual machine", RuntimeWarning, stacklevel=2)
        return function
    name = function.name()
    with tempfile.TemporaryDirectory() as scratch:
        generator = casadi.CodeGenerator(f"{name}.c", {"with_header": False})
        generator.add(function)
        generator.generate(scratch + os.sep)
        source = Path(scratch, f"{name}.c").read_text()
    key = hashlib.sha256((source + " ".join(flags)).encode()).hexdigest()[:16]
    directory = cache_directory()
    library = directory / f"{name}_{key}.so"
    if not library.exists():
        directory.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=directory) as build:
            c_file = Path(build, f"{name}.c")
            c_file.write_text(source)
            target = Path(build, library.name)
            try:
                result = subprocess.run([compiler, *flags, "-shared", "-fPIC", str(c_file), "-o", str(target), "-lm"], capture_output=True, text=True)
                failure = result.stderr.strip()[:200] if result.returncode != 0 else None
            except OSError as error:
                failure = str(error)
            if failure is not None:
                warnings.warn(f"compiling {name} with {compiler} failed ({failure}): using the CasADi virtual machine", RuntimeWarning, stacklevel=2)
                return function
            os.replace(target, library)  # atomic: a concurrent process sees no half-written library
    return casadi.external(name, str(library))
