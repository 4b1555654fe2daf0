"""The ``oed`` verbs as library calls: one module a verb, each with one function (``identify``, ``diagnose``…)
that takes the verb's options as keyword arguments of the same names and returns a frozen run object
(``to_dict()``: the JSON the verb writes; ``write(...)``: all of its files or none; ``summary()``: the lines it
prints). :mod:`oed` re-exports the functions (``oed.identify(...)``); the command line (:mod:`oed.cli`) parses
options, calls them and prints.

What several verbs share: :mod:`.options` (the option sets, the robot, derivatives, streaming settings),
:mod:`.asbuilt` (the robot as built: transmission, effects, rest rows, trivial predictors, the document's
common keys), :mod:`.memory_path` (in memory or streamed), :mod:`.model_files` (the model file and plausibility
keys), :mod:`.chosen_model` (the top-level answer of result.json and report.json: the chosen model's),
:mod:`.consistent` (the prior-weight choice of ``--consistent``), :mod:`.design_bounds` (the motion bounds of
``oed design``), :mod:`.diagnosis_training` (the streamed diagnosis's training errors against the recording).
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "CONTROLLERS": "oed.workflows.simulate",
    "DATA_SUFFIXES": "oed.workflows.simulate",
    "DEFAULT_PRIOR_WEIGHT": "oed.workflows.consistent",
    "DesignOptions": "oed.workflows.design",
    "DiagnoseOptions": "oed.workflows.diagnose",
    "IPOPT_ALONE": "oed.workflows.design",
    "IdentifyOptions": "oed.workflows.identify",
    "PRIOR_WEIGHT_GRID": "oed.workflows.consistent",
    "PRIOR_WEIGHT_TOLERANCE": "oed.workflows.consistent",
    "RecordOptions": "oed.workflows.options",
    "SimulateOptions": "oed.workflows.simulate",
    "check_csv_path": "oed.workflows.options",
    "check_json_path": "oed.workflows.options",
    "check_markdown_path": "oed.workflows.options",
    "residual_figure": "oed.workflows.diagnose",
    "trace_figure": "oed.workflows.diagnose",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
