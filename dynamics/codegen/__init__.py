"""Compiled code: the regressors compiled once with the system C compiler (:mod:`dynamics.codegen.compiled`)
the on-disk cache of the design's just-in-time compiled functions (:mod:`dynamics.codegen.jit_cache`) and that of
built IPOPT solvers (:mod:`dynamics.codegen.solver_cache`)."""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "SampleEvaluator": "dynamics.codegen.compiled",
    "cache_directory": "dynamics.codegen.compiled",
    "cached_jit": "dynamics.codegen.jit_cache",
    "cached_nlpsol": "dynamics.codegen.solver_cache",
    "compile_function": "dynamics.codegen.compiled",
    "find_compiler": "dynamics.codegen.compiled",
    "jit_directory": "dynamics.codegen.jit_cache",
    "library_path": "dynamics.codegen.jit_cache",
    "solver_directory": "dynamics.codegen.solver_cache",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
