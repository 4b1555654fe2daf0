"""Measured records read with checks: columns, time base, units, log cleaning, motor-side channels, rows at rest, segments.

Modules: :mod:`~estimation.data.loading`, :mod:`~estimation.data.log_cleaning`, :mod:`~estimation.data.motor_side`, :mod:`~estimation.data.records`, :mod:`~estimation.data.rest`, :mod:`~estimation.data.segments`.
"""
