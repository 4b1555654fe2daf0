"""Run-time helpers that depend on nothing else in the project: thread budgets, memory guards, safe output files.

Modules: :mod:`~dynamics.runtime.memory`, :mod:`~dynamics.runtime.output_files`, :mod:`~dynamics.runtime.threads`.
"""
