"""Physically consistent identification: every link a rigid body and friction that dissipates (IPOPT), the simulation of the estimate, and the default answer of ``oed identify`` chosen among it and the unconstrained fits.

Modules: :mod:`~estimation.consistent.identification`, :mod:`~estimation.consistent.least_squares`, :mod:`~estimation.consistent.model_selection`, :mod:`~estimation.consistent.reduced_hessian`, :mod:`~estimation.consistent.simulation`, :mod:`~estimation.consistent.solver`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "ConsistentLeastSquares": "estimation.consistent.least_squares",
    "ConsistentResult": "estimation.consistent.identification",
    "ConsistentSolverError": "estimation.consistent.least_squares",
    "RELATIVE_STD_THRESHOLD": "estimation.consistent.determination",
    "consistent_controller": "estimation.consistent.simulation",
    "consistent_robot": "estimation.consistent.simulation",
    "consistent_simulator": "estimation.consistent.simulation",
    "identify_consistent": "estimation.consistent.identification",
    "load_link_bounds": "estimation.consistent.identification",
    "load_prior": "estimation.consistent.identification",
    "mass_matrix_eigenvalues": "estimation.consistent.simulation",
    "measured_reference": "estimation.consistent.simulation",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
