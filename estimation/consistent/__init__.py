"""Physically consistent identification: every link a rigid body and friction that dissipates (IPOPT), the simulation of the estimate, and the default answer of ``oed identify`` chosen among it and the unconstrained fits.

Modules: :mod:`~estimation.consistent.identification`, :mod:`~estimation.consistent.least_squares`, :mod:`~estimation.consistent.model_selection`, :mod:`~estimation.consistent.reduced_hessian`, :mod:`~estimation.consistent.simulation`, :mod:`~estimation.consistent.solver`.
"""
