"""The ``oed`` verbs as library calls: one module a verb, each with one function (``identify``, ``diagnose``…)
that takes the verb's options as keyword arguments of the same names and returns a frozen run object
(``to_dict()``: the JSON the verb writes; ``write(...)``: all of its files or none; ``summary()``: the lines it
prints). :mod:`oed` re-exports the functions (``oed.identify(...)``); the command line (:mod:`oed.cli`) parses
options, calls them and prints.

What several verbs share: :mod:`.options` (the option sets, the robot, derivatives, streaming settings),
:mod:`.asbuilt` (the robot as built: transmission, effects, rest rows, trivial predictors, the document's
common keys), :mod:`.memory_path` (in memory or streamed), :mod:`.model_files` (the model file and plausibility
keys), :mod:`.consistent` (the prior-weight choice of ``--consistent``), :mod:`.design_bounds` (the motion
bounds of ``oed design``).
"""
