"""An on-disk cache of built nonlinear-program solvers (``casadi.nlpsol``).

Building an IPOPT solver generates its derivative functions (the objective's gradient, the constraints' Jacobian,
the Lagrangian's Hessian) from the problem's expression graph: for the consistent problem of a 7-joint arm
(:mod:`estimation.consistent.solver`) 0.2 s of CPU a model, every run. :func:`cached_nlpsol` builds a solver once,
keeps CasADi's serialization of it (``Function.save``: the problem, the generated functions and the options) in
``<cache>/nlpsol`` (``$ROBOT_OED_CACHE/nlpsol``, by default ``~/.cache/robot-oed/nlpsol``; see
:mod:`dynamics.codegen.compiled`; the :data:`KEPT_SOLVERS` most recently used), keyed by a hash of the problem's serialization, the solver plugin and name, the
options and the CasADi version, and later processes load it (``Function.load``, 0.07 s): the same functions, so the
same iterates. Every failure (a directory that cannot be written, a file that does not load) builds the solver as
``casadi.nlpsol`` does.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path
from typing import Any

import casadi

from dynamics.codegen.compiled import cache_directory


#: the most solvers the cache keeps (a 7-joint arm's consistent problem is 10 MB): the least recently used go
KEPT_SOLVERS = 32


def solver_directory() -> Path:
    """Where :func:`cached_nlpsol` keeps its solvers: ``<cache>/nlpsol``."""
    return cache_directory() / "nlpsol"


def solver_key(name: str, plugin: str, nlp: dict[str, casadi.SX], options: dict[str, Any]) -> str:
    """The hash that names a solver's cache entry (module docstring)."""
    keys = sorted(nlp)
    inputs = [key for key in keys if key in ("x", "p")]
    outputs = [key for key in keys if key not in inputs]
    oracle = casadi.Function("nlp", [nlp[key] for key in inputs], [nlp[key] for key in outputs], inputs, outputs)
    fingerprint = "\n".join((name, plugin, ",".join(keys), oracle.serialize(), repr(sorted(options.items())),
                             casadi.__version__))
    return hashlib.sha256(fingerprint.encode()).hexdigest()[:20]


def cached_nlpsol(name: str, plugin: str, nlp: dict[str, casadi.SX], options: dict[str, Any]) -> casadi.Function:
    """``casadi.nlpsol(name, plugin, nlp, options)``, loaded from the on-disk cache when it was built before (module
    docstring). Options that hold functions (derivatives given to the solver) are not cached: built as asked."""
    if any(isinstance(value, casadi.Function) for value in options.values()):
        return casadi.nlpsol(name, plugin, nlp, options)
    try:
        path: Path | None = solver_directory() / f"{name}_{solver_key(name, plugin, nlp, options)}.casadi"
    except RuntimeError:  # a problem CasADi cannot serialize: built as asked
        path = None
    try:
        if path is not None and path.exists():
            loaded = casadi.Function.load(str(path))
            os.utime(path)  # used: among the latest for :func:`_trim`
            return loaded
    except (OSError, RuntimeError):  # a damaged entry: built again and written anew
        pass
    solver = casadi.nlpsol(name, plugin, nlp, options)
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            descriptor, temporary = tempfile.mkstemp(prefix=".robot-oed-", suffix=".casadi", dir=path.parent)
            os.close(descriptor)
            try:
                solver.save(temporary)
                os.replace(temporary, path)  # atomic: a concurrent reader never sees half a file
            finally:
                if os.path.exists(temporary):
                    os.unlink(temporary)
            _trim(path.parent)
        except (OSError, RuntimeError):
            pass
    return solver


def _trim(directory: Path) -> None:
    """Only the :data:`KEPT_SOLVERS` most recently used solvers kept (written or loaded: the files' times)."""
    entries = sorted(directory.glob("*.casadi"), key=lambda entry: entry.stat().st_mtime)
    for entry in entries[:-KEPT_SOLVERS]:
        entry.unlink(missing_ok=True)
