"""The final model's parameter vector as JSON, reusable without the Python API.

``result.json`` (``oed identify``) and ``report.json`` (``oed diagnose``) carry::

    "model_parameters": {
        "model": "internal", "robot": "puma560",
        "effects": "viscous,coulomb@2+5,coulomb[q5+q6]",      # the spec that rebuilds the model
        "transmission": {"matrix": [[...]], ...} | null,      # when motor-side effects need it
        "channels": ["tau1", ...],
        "names": [...], "expressions": [...], "values": [...], "std": [...],
        "shape": {"vc1": 0.05, ...}, "shape_std": {...},       # laws with shape parameters (coulomb:tanh…)
        "smoothing": {"coulomb@2": 0.05}}                     # Coulomb laws smoothed at rest (--rest smooth)

``names`` are the base parameters, ``expressions`` the standard parameters each groups
(``Izz2R = Izz2 - a2**2*(m2 + m3)``); ``values`` and ``std`` their estimates and standard
deviations, in the columns' order of ``build_model(robot, model, effects).base_regressor``, so
``Y_base @ values`` predicts the channels.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dynamics.effects.specs import effect_spec
from estimation.identification.fit import IdentificationResult


def model_parameters(result: IdentificationResult, transmission: Any = None) -> dict[str, Any]:
    """The ``model_parameters`` document of ``result`` (see the module docstring)."""
    model, estimate = result.model, result.estimate
    uses_motors = any(getattr(effect, "motor", False) for effect in model.effects)
    return {
        "model": model.kind.value,
        "robot": model.robot.name,
        "effects": ",".join(effect_spec(effect) for effect in model.effects) or "none",
        "transmission": transmission.to_dict() if uses_motors and transmission is not None else None,
        "channels": list(model.channels),
        "names": list(estimate.names),
        "expressions": list(estimate.expressions),
        "values": [float(value) for value in estimate.values],
        "std": [float(value) if np.isfinite(value) else None for value in estimate.std],
        # the shape parameters of laws such as coulomb:tanh (the columns above are at these values),
        # and the fixed smoothing of Coulomb laws smoothed for rows at rest (--rest smooth)
        "shape": {value.name: float(value.value) for value in getattr(result, "shapes", ())},
        "shape_std": {value.name: float(value.std) for value in getattr(result, "shapes", ())},
        "smoothing": {effect_spec(effect): float(effect.smoothing) for effect in model.effects
                      if getattr(effect, "smoothing", None) is not None and not hasattr(effect, "spec")},
    }
