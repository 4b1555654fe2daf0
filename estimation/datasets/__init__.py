"""Read-only loaders of the shared real data sets (EMPS, KUKA LWR4+, DaISy) and the EMPS axis model.

Modules: :mod:`~estimation.datasets.emps_model`, :mod:`~estimation.datasets.kuka`, :mod:`~estimation.datasets.shared`.
"""
