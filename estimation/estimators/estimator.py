"""What every estimator shares, after scikit-learn's ``BaseEstimator``.

Settings are keyword-only ``__init__`` arguments stored under their own names, with
``get_params``/``set_params`` and a repr of them; ``fit`` starts afresh (no fitted attribute of an
earlier fit survives).
"""

from __future__ import annotations

import inspect
from typing import Any

from estimation.estimators.errors import NotFittedError


class Estimator:
    """Mixin: ``get_params``, ``set_params``, ``__repr__`` from the ``__init__`` signature."""

    @classmethod
    def _parameter_names(cls) -> list[str]:
        signature = inspect.signature(cls.__init__)
        return [name for name, parameter in signature.parameters.items()
                if name != "self" and parameter.kind is inspect.Parameter.KEYWORD_ONLY]

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The settings, by name (``deep`` is accepted for scikit-learn compatibility)."""
        return {name: getattr(self, name) for name in self._parameter_names()}

    def set_params(self, **settings: Any) -> Estimator:
        """Change settings by name; returns ``self``. Unknown names are a ``ValueError``."""
        known = self._parameter_names()
        unknown = sorted(set(settings) - set(known))
        if unknown:
            raise ValueError(f"{type(self).__name__} has no setting(s) {unknown}; its settings are {known}")
        for name, value in settings.items():
            setattr(self, name, value)
        return self

    def _forget_fit(self) -> None:
        """Drop the fitted attributes (names ending in ``_``) of an earlier ``fit``."""
        for name in [name for name in vars(self) if name.endswith("_") and not name.startswith("_")]:
            delattr(self, name)

    def __getattr__(self, name: str) -> Any:
        # only reached when the attribute is missing: a fitted value asked for before fit
        if name.endswith("_") and not name.startswith("_"):
            raise NotFittedError(f"{type(self).__name__} is not fitted yet ({name} is set by fit): call fit first")
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __repr__(self) -> str:
        settings = ", ".join(f"{name}={value!r}" for name, value in self.get_params().items())
        return f"{type(self).__name__}({settings})"
