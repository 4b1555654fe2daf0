"""Physically consistent identification: every link a rigid body and friction that dissipates (IPOPT), and the simulation of the estimate.

Modules: :mod:`~estimation.consistent.identification`, :mod:`~estimation.consistent.least_squares`, :mod:`~estimation.consistent.reduced_hessian`, :mod:`~estimation.consistent.simulation`, :mod:`~estimation.consistent.solver`.
"""
