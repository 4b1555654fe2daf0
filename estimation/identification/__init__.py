"""Identification of a model on one experiment and validation on another: the records read and prepared in one call
(the derivatives chosen by held-out evidence), plain, shaped and delayed fits, the model's parameter vector as JSON,
trivial predictors.

Modules: :mod:`~estimation.identification.delayed`, :mod:`~estimation.identification.fit`, :mod:`~estimation.identification.model_parameters`, :mod:`~estimation.identification.prepared`, :mod:`~estimation.identification.preprocessing_choice`, :mod:`~estimation.identification.shaped`, :mod:`~estimation.identification.trivial_predictors`, :mod:`~estimation.identification.validation`.

``from estimation.identification import identify`` (the path release 0.1 showed) still works for one release, with a
DeprecationWarning: import it from :mod:`estimation.identification.fit`.
"""

import importlib
import warnings
from typing import Any


def __getattr__(name: str) -> Any:
    """The deprecated alias ``estimation.identification.identify`` (see docs/migration.md)."""
    if name == "identify":
        warnings.warn(
            "estimation.identification.identify is deprecated and will be removed in the next release; "
            "import it from estimation.identification.fit",
            DeprecationWarning,
            stacklevel=2,
        )
        return importlib.import_module("estimation.identification.fit").identify
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
