"""Measured records read with checks: columns, time base, units, log cleaning, motor-side channels, rows at rest, segments.

Modules: :mod:`~estimation.data.loading`, :mod:`~estimation.data.log_cleaning`, :mod:`~estimation.data.motor_side`, :mod:`~estimation.data.records`, :mod:`~estimation.data.rest`, :mod:`~estimation.data.segments`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "AbsurdValueError": "estimation.data.loading",
    "AngleUnitError": "estimation.data.loading",
    "UnwrappedAngleWarning": "estimation.data.loading",
    "HoldWarning": "estimation.data.loading",
    "WrappedAngleError": "estimation.data.loading",
    "ConstantChannelError": "estimation.data.segments",
    "DEFAULT_MAX_GAP": "estimation.data.log_cleaning",
    "DEFAULT_TOPIC": "estimation.data.log_formats",
    "DEGREES_THRESHOLD": "estimation.data.loading",
    "GAP_FACTOR": "estimation.data.loading",
    "DuplicatedTimesWarning": "estimation.data.loading",
    "DelimiterWarning": "estimation.data.loading",
    "UnitsRowWarning": "estimation.data.loading",
    "HoleError": "estimation.data.loading",
    "IRREGULAR_TOLERANCE": "estimation.data.loading",
    "InMemoryNeed": "estimation.data.memory_budget",
    "JointCountError": "estimation.data.loading",
    "LogSource": "estimation.data.log_formats",
    "MeasurementError": "estimation.data.loading",
    "MeasurementWarning": "estimation.data.loading",
    "MemorySizeError": "estimation.data.memory_budget",
    "MissingColumnError": "estimation.data.loading",
    "NonFiniteError": "estimation.data.loading",
    "ParquetSupportError": "estimation.data.loading",
    "RepeatedRowsWarning": "estimation.data.loading",
    "RepeatedHeaderWarning": "estimation.data.loading",
    "BlankRowsWarning": "estimation.data.loading",
    "ResampledWarning": "estimation.data.loading",
    "ReceiveTimesWarning": "estimation.data.loading",
    "clock_roughness": "estimation.data.sampling_clock",
    "RestHandling": "estimation.data.rest",
    "RestSelection": "estimation.data.rest",
    "RosSupportError": "estimation.data.log_formats",
    "SegmentColumnsError": "estimation.data.segments",
    "StallWarning": "estimation.data.loading",
    "CoarseStampsWarning": "estimation.data.loading",
    "StillJointWarning": "estimation.data.loading",
    "TimeBaseError": "estimation.data.loading",
    "TooFewSamplesError": "estimation.data.loading",
    "UnknownTopicError": "estimation.data.log_formats",
    "as_segments": "estimation.data.segments",
    "check_min_speed": "estimation.data.rest",
    "check_same_columns": "estimation.data.segments",
    "check_time": "estimation.data.loading",
    "check_varying_channels": "estimation.data.segments",
    "column_set": "estimation.data.segments",
    "concatenate": "estimation.data.segments",
    "coulomb_combinations": "estimation.data.rest",
    "count_rows": "estimation.data.memory_budget",
    "default_budget": "estimation.data.memory_budget",
    "drop_rest": "estimation.data.rest",
    "holds": "estimation.data.rest",
    "held_rows": "estimation.data.rest",
    "without_holds": "estimation.data.rest",
    "estimate_in_memory": "estimation.data.memory_budget",
    "format_size": "estimation.data.memory_budget",
    "is_log_file": "estimation.data.log_formats",
    "joint_side_frame": "estimation.data.motor_side",
    "measurements_from_frame": "estimation.data.records",
    "parse_column_map": "estimation.data.log_formats",
    "parse_memory_size": "estimation.data.memory_budget",
    "read_log_frame": "estimation.data.log_formats",
    "read_measurements": "estimation.data.records",
    "read_record": "estimation.data.records",
    "read_record_with_transmission": "estimation.data.motor_side",
    "segment_slices": "estimation.data.segments",
    "smooth_coulomb": "estimation.data.rest",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
