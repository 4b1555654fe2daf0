"""Typed errors of the toolkit. All derive from ``ValueError`` so that callers may catch either."""

from __future__ import annotations


class RobotDescriptionError(ValueError):
    """A robot description (URDF, DH table, built-in name) cannot be turned into a serial chain."""


class SampleShapeError(ValueError):
    """Arrays of joint states or measurements have the wrong shape or hold NaN/inf."""
