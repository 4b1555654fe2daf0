"""The ``oed`` verbs: the name a user types, the module of this package that holds it and the line ``oed
--help`` lists for it.

A verb's module imports what its work needs (NumPy, SciPy, CasADi, Pinocchio, pandas): about a second on a
shared 2-core machine, and a run needs one verb. :func:`oed.cli.build_parser` imports the module of the verb
asked for alone; the others are listed from this table.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["VERBS", "Verb", "verb_summary"]


@dataclass(frozen=True)
class Verb:
    """One verb: ``name`` as typed (``servo-fit``), ``module`` in :mod:`oed.cli` (``servo_fit``) and its
    one-line ``summary``."""

    name: str
    module: str
    summary: str


#: every verb, in the order ``oed --help`` lists them
VERBS: tuple[Verb, ...] = (
    Verb("model", "model", "print the base parameters of the three identification models"),
    Verb("design", "design", "optimise a periodic Fourier excitation trajectory"),
    Verb("simulate", "simulate", "simulate a robot tracking a trajectory and write measurements"),
    Verb("identify", "identify", "estimate base parameters from measured motion and torques/wrench"),
    Verb("aprbs", "aprbs", "design an APRBS excitation for the servo arm (CSV t,u1..uJ in rad)"),
    Verb("servo-simulate", "servo_simulate", "simulate the servo arm (Kalman-fused angles) from an APRBS CSV"),
    Verb("servo-fit", "servo_fit", "fit second-order joint models to t,u1..uJ,q1..qJ data (JSON out)"),
    Verb("diagnose", "diagnose", "find the effects a model lacks in measured data and report the error before and after"),
    Verb("predict", "predict", "predict the torques/wrench of a record with an identified model, and its errors"),
    Verb("payload", "payload", "identify a payload's mass, centre of mass and inertia with the robot's model held fixed"),
    Verb("export", "export", "write a consistent identified model as a URDF (and its friction as JSON)"),
    Verb("demo", "demo", "the whole loop on the built-in PUMA 560: design, simulate, identify, diagnose, re-identify"),
)


def verb_summary(name: str) -> str:
    """The line ``oed --help`` lists for the verb ``name``."""
    for verb in VERBS:
        if verb.name == name:
            return verb.summary
    raise KeyError(f"no verb {name!r}")
