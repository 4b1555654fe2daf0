"""Velocities and accelerations from measured positions: differentiation (filters, Fourier fits), periodicity, the preprocessing plan of an identification, the delay between torques and motion.

Modules: :mod:`~estimation.preprocessing.delay`, :mod:`~estimation.preprocessing.differentiation`, :mod:`~estimation.preprocessing.fourier_series`, :mod:`~estimation.preprocessing.periodicity`, :mod:`~estimation.preprocessing.plan`.
"""
