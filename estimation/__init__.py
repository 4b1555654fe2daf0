"""Estimation from measured data, in subpackages by idea (layers from the bottom up): ``data``, ``preprocessing``,
``uncertainty``, ``estimators``, ``identification``, ``consistent``, ``diagnosis``, ``streaming``; beside them ``servo``
(the servo-arm paper) and ``datasets`` (loaders of the shared real data sets)."""
