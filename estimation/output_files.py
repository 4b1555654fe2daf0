"""Writing result files safely now lives in :mod:`dynamics.output_files` (it depends on nothing in the
project, and :meth:`dynamics.measurements.Measurements.write` uses it). Re-exported here so that
every existing import keeps working.
"""

from dynamics.output_files import (  # noqa: F401
    FIGURE_DEFAULT_SUFFIX,
    file_mode,
    check_figure_path,
    OutputFiles,
    _temporary_prefix,
    _process_alive,
    remove_stale_temporaries,
    atomic_output,
    save_figure,
    _finite_or_null,
    json_text,
)

__all__ = ["FIGURE_DEFAULT_SUFFIX", "file_mode", "check_figure_path", "OutputFiles", "remove_stale_temporaries", "atomic_output", "save_figure", "json_text"]
