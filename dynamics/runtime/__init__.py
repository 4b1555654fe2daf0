"""Run-time helpers that depend on nothing else in the project: thread budgets, memory guards, safe output files.

Modules: :mod:`~dynamics.runtime.memory`, :mod:`~dynamics.runtime.output_files`, :mod:`~dynamics.runtime.threads`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "InsufficientMemoryError": "dynamics.runtime.memory",
    "OutputFiles": "dynamics.runtime.output_files",
    "SECONDS": "dynamics.runtime.progress",
    "TaskError": "dynamics.runtime.processes",
    "atomic_output": "dynamics.runtime.output_files",
    "available_cores": "dynamics.runtime.threads",
    "available_memory": "dynamics.runtime.memory",
    "check_allocation": "dynamics.runtime.memory",
    "check_figure_path": "dynamics.runtime.output_files",
    "is_staged": "dynamics.runtime.output_files",
    "json_text": "dynamics.runtime.output_files",
    "keep_freed_memory": "dynamics.runtime.allocator",
    "report": "dynamics.runtime.progress",
    "run_tasks": "dynamics.runtime.processes",
    "sample_thread_limit": "dynamics.runtime.threads",
    "save_figure": "dynamics.runtime.output_files",
    "show_progress": "dynamics.runtime.progress",
    "single_threaded": "dynamics.runtime.threads",
    "single_threaded_blas": "dynamics.runtime.threads",
    "step": "dynamics.runtime.progress",
    "total_memory": "dynamics.runtime.memory",
    "worker_count": "dynamics.runtime.processes",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
