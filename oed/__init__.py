"""robot-oed: optimal experiment design and dynamic-parameter identification of robot manipulators.

The import packages are:

- :mod:`dynamics`: robot descriptions and the symbolic Newton–Euler regressors (CasADi);
- :mod:`oed`: excitation design (Fourier trajectories, APRBS) and the ``oed`` command line;
- :mod:`estimation`: estimators (least squares, recursive least squares, Kalman fusion).
"""

__version__ = "0.1.0"
