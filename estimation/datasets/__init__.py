"""Read-only loaders of the shared real data sets (EMPS, KUKA LWR4+, DaISy) and the EMPS axis model.

Modules: :mod:`~estimation.datasets.emps_model`, :mod:`~estimation.datasets.kuka`, :mod:`~estimation.datasets.shared`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "emps_measurements": "estimation.datasets.shared",
    "fit_emps_second_order": "estimation.datasets.emps_model",
    "load_daisy_robot_arm": "estimation.datasets.shared",
    "load_emps": "estimation.datasets.shared",
    "load_kuka_run": "estimation.datasets.kuka",
    "validate_emps": "estimation.datasets.emps_model",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
