"""Estimation from measured data, in subpackages by idea (layers from the bottom up): ``data``, ``preprocessing``,
``uncertainty``, ``estimators``, ``identification``, ``consistent``, ``diagnosis``, ``streaming``; beside them ``servo``
(the servo-arm paper) and ``datasets`` (loaders of the shared real data sets)."""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "identify": "estimation.identification.fit",
    "noise_floor": "estimation.uncertainty.noise_floor",
    "prepare_records": "estimation.identification.prepared",
    "read_record": "estimation.data.records",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
