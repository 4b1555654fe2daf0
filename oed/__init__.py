"""robot-oed: optimal experiment design and dynamic-parameter identification of robot manipulators.

The import packages are:

- :mod:`dynamics`: robot descriptions and the symbolic Newton–Euler regressors (CasADi);
- :mod:`oed`: excitation design (Fourier trajectories, APRBS), the verbs as library calls and the ``oed``
  command line;
- :mod:`estimation`: estimators (least squares, recursive least squares, Kalman fusion).

Each ``oed`` verb is a function here, taking the verb's options as keywords of the same names and returning a
run object (``to_dict()``, ``write(...)``, ``summary()``; :mod:`oed.workflows`)::

    import oed
    run = oed.identify(robot="puma560", joints=3, data="train.csv", validate="validate.csv")
    run.write("result.json")

The functions are imported on first use (``import oed`` stays light for the command line).
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

#: each verb function and the module of :mod:`oed.workflows` that holds it
VERB_FUNCTIONS: dict[str, str] = {
    "model": "model",
    "design": "design",
    "simulate": "simulate",
    "identify": "identify",
    "aprbs": "aprbs",
    "servo_simulate": "servo_simulate",
    "servo_fit": "servo_fit",
    "diagnose": "diagnose",
    "predict": "predict",
    "export": "export",
    "payload": "payload",
}

__all__ = ["__version__", *VERB_FUNCTIONS]


def __getattr__(name: str) -> Any:
    """The verb functions, imported when first asked for (PEP 562)."""
    if name in VERB_FUNCTIONS:
        module = importlib.import_module(f"oed.workflows.{VERB_FUNCTIONS[name]}")
        return getattr(module, name)
    raise AttributeError(f"module 'oed' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *VERB_FUNCTIONS])
