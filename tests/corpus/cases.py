"""The corpus as one table: each case's truth, what the diagnosis must name, and how close it must end.

A :class:`Case` is simulated in the library (:mod:`tests.corpus.records`): a 3-joint PUMA 560 whose torques are the
declared model (rigid body and viscous friction) plus the case's true terms, white noise of :data:`NOISE` N·m on
every channel, two records from different trajectories (training, validation). Its targets:

* ``named``: the ``(spec, channel)`` pairs the diagnosis names, exactly (the right family on the right channel,
  nothing of another family, nothing at all on a clean record); ``a|b`` accepts either spec;
* ``floor_tolerance``: each channel's final validation MSE over its noise floor (the noise variance, known here);
* each channel's final validation MSE over that of a fit that knows the true law (from the same records and
  derivatives): at most 1.2 with measured derivatives, 1.5 from positions only (``Case.known_law_tolerance``);
* the estimates of every true parameter named (linear and shape) within :data:`SIGMAS` standard deviations.

``xfail`` holds the figures measured on the code of the day when a case misses a target (never a weaker target).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from dynamics.effects.linear import Armature, CoulombFriction, JointOffset, Spring
from dynamics.effects.motor import CombinationEffect
from dynamics.effects.shaped import (
    PositionRipple,
    ShapedStribeckFriction,
    SigmoidFriction,
    TanhCoulombFriction,
)

NOISE = 0.1  # N·m on every torque channel
SIGMAS = 4.0  # an estimate further than this many standard deviations from the truth is wrong
KNOWN_LAW_GIVEN = 1.2  # final validation MSE over that of a fit that knows the true law, derivatives measured
KNOWN_LAW_POSITIONS = 1.5  # the same, derivatives made from the positions


@dataclass(frozen=True)
class TrueTerm:
    """One effect of the truth: an effect of :mod:`dynamics.effects` with its linear coefficients and shape."""

    effect: Any
    coefficients: tuple[float, ...]
    shape: tuple[float, ...] = ()


@dataclass(frozen=True)
class Case:
    """A simulated case and the outcome the diagnosis loop must reach on it (module docstring)."""

    name: str
    terms: tuple[TrueTerm, ...]
    named: frozenset[tuple[str, str]]
    derivatives: Literal["given", "positions"] = "given"
    delay: float = 0.0
    floor_tolerance: float = 1.5
    xfail: str = ""
    slow: bool = False
    seeds: tuple[int, int] = (3, 4)

    def __post_init__(self) -> None:
        if self.derivatives not in ("given", "positions"):
            raise ValueError(f"case {self.name}: derivatives must be 'given' or 'positions', got {self.derivatives!r}")

    @property
    def known_law_tolerance(self) -> float:
        return KNOWN_LAW_GIVEN if self.derivatives == "given" else KNOWN_LAW_POSITIONS


def named(*pairs: tuple[str, str]) -> frozenset[tuple[str, str]]:
    return frozenset(pairs)


def positions_only(case: Case, **changes: Any) -> Case:
    """The same truth, the derivatives made from the positions (chosen by held-out evidence, as a user gets them)."""
    settings = {"name": f"{case.name}/positions", "derivatives": "positions", "xfail": "", "slow": True}
    settings.update(changes)
    return Case(**{**{key: getattr(case, key) for key in Case.__dataclass_fields__}, **settings})


SIGN_COULOMB = TrueTerm(CoulombFriction(joints=(1,)), (6.0,))
TANH_COULOMB = TrueTerm(TanhCoulombFriction(joints=(1,)), (6.0,), (0.03,))
STRIBECK = TrueTerm(ShapedStribeckFriction(joints=(2,)), (2.0, 3.0), (0.2,))
SIGMOID = TrueTerm(SigmoidFriction(joints=(1,)), (8.0,), (40.0, 0.15))
OFFSET = TrueTerm(JointOffset(joints=(0,)), (1.5,))
SPRING = TrueTerm(Spring(joints=(0,)), (12.0,))
ARMATURE = TrueTerm(Armature(joints=(2,)), (2.0,))
RIPPLE = TrueTerm(PositionRipple(joints=(2,)), (1.2, -0.8), (7.3,))
COUPLED = TrueTerm(CombinationEffect("coulomb", ((0.0, 1.0, 1.0),), ("q2+q3",)), (3.0,))

ALONE: tuple[Case, ...] = (
    Case("clean", (), named()),
    Case("coulomb sign", (SIGN_COULOMB,), named(("coulomb", "tau2"))),
    Case("coulomb tanh", (TANH_COULOMB,), named(("coulomb:tanh", "tau2"))),
    Case("stribeck", (STRIBECK,), named(("stribeck:velocity", "tau3"))),
    Case("sigmoid", (SIGMOID,), named(("sigmoid", "tau2"))),
    Case("offset", (OFFSET,), named(("offset", "tau1"))),
    Case("spring", (SPRING,), named(("spring", "tau1"))),
    Case("armature", (ARMATURE,), named(("armature", "tau3"))),
    Case("ripple", (RIPPLE,), named(("ripple", "tau3"))),
    Case("delay", (), named(("delay", "tau1"), ("delay", "tau2"), ("delay", "tau3")), delay=0.007),
    Case("coupled coulomb q2+q3", (COUPLED,), named(("coulomb[q2+q3]", "tau2"), ("coulomb[q2+q3]", "tau3"))),
)

PAIRS: tuple[Case, ...] = (
    Case("coulomb + offset", (TrueTerm(CoulombFriction(joints=(0,)), (6.0,)), TrueTerm(JointOffset(joints=(0,)), (-1.0,))),
         named(("coulomb", "tau1"), ("offset", "tau1"))),
    Case("stribeck + offset", (STRIBECK, TrueTerm(JointOffset(joints=(2,)), (0.8,))),
         named(("stribeck:velocity", "tau3"), ("offset", "tau3"))),
    # k (q − q_ref) with q_ref = 0.1 rad: a spring and an offset of −k q_ref on one joint
    Case("spring + offset", (SPRING, TrueTerm(JointOffset(joints=(0,)), (-1.2,))),
         named(("spring", "tau1"), ("offset", "tau1"))),
    Case("coulomb + spring, two joints", (SIGN_COULOMB, TrueTerm(Spring(joints=(2,)), (8.0,))),
         named(("coulomb", "tau2"), ("spring", "tau3"))),
)

NON_DEFAULT: tuple[Case, ...] = (
    Case("coulomb on every joint", (TrueTerm(CoulombFriction(), (4.0, 9.0, 2.5)),),
         named(("coulomb", "tau1"), ("coulomb", "tau2"), ("coulomb", "tau3"))),
    Case("stribeck on every joint", (TrueTerm(ShapedStribeckFriction(joints=(0,)), (3.0, 2.0), (0.15,)),
                                     TrueTerm(ShapedStribeckFriction(joints=(1,)), (5.0, 3.0), (0.3,)),
                                     TrueTerm(ShapedStribeckFriction(joints=(2,)), (2.0, 3.0), (0.2,))),
         named(("stribeck:velocity", "tau1"), ("stribeck:velocity", "tau2"), ("stribeck:velocity", "tau3")), slow=True),
    Case("small offset, tau1", (TrueTerm(JointOffset(joints=(0,)), (0.15,)),), named(("offset", "tau1"))),
    # joint 2 and 3 carry gravity: over these records the rigid-body columns take up most of an offset
    Case("offset on a gravity-loaded joint, tau3", (TrueTerm(JointOffset(joints=(2,)), (0.15,)),),
         named(("offset", "tau3"))),
    Case("weak spring, tau1", (TrueTerm(Spring(joints=(0,)), (3.0,)),), named(("spring", "tau1"))),
)

#: measured on the code of the day, where a case from positions only misses its targets
POSITIONS_XFAIL: dict[str, str] = {
    "coulomb sign": "measured: named coulomb@tau2 (the sign law, the truth); after/floor 0.99/2.42/0.98, after/known "
                    "law 1.00/1.00/1.00: only the floor is missed, and the fit that knows the law misses it as much "
                    "(derivatives: a Fourier fit chosen by held-out evidence; a sign law's jump is smoothed by any "
                    "derivative from positions)",
}
POSITIONS: tuple[Case, ...] = tuple(
    positions_only(case, xfail=POSITIONS_XFAIL.get(case.name, "")) for case in ALONE + PAIRS[:3]
    if case.name != "coupled coulomb q2+q3"
)

CASES: tuple[Case, ...] = ALONE + PAIRS + NON_DEFAULT + POSITIONS


@dataclass(frozen=True)
class LoopCase:
    """A user's loop through the CLI on files, and its targets (see :mod:`tests.corpus.test_user_loops`)."""

    name: str
    named: frozenset[tuple[str, str]]
    floor_tolerance: float | None = 1.5
    after_over_before: float | None = None
    xfail: str = ""


# the simulator's Coulomb law is tanh(dq / 0.05): the sign law or the tanh law names it
COULOMB_LIKE = "coulomb|coulomb:tanh"
README_LOOP = LoopCase(
    "README loop",
    named(*((family, f"tau{joint}") for joint in (1, 2, 3) for family in (COULOMB_LIKE, "offset"))),
)
EMPS_LOOP = LoopCase(
    "EMPS, no flags",
    named((COULOMB_LIKE, "tau1"), ("offset", "tau1")),
    floor_tolerance=None,
    after_over_before=0.3,
    xfail="measured: named sigmoid@tau1 (a shifted sigmoid, phi3 = 0.00048 ± 0.00002 m/s: the asymmetric law a "
          "symmetric law beside an offset approximates); validation MSE 418.7 -> 329.2 (after/before 0.786), at its noise "
          "floor (0.99x: no model can go lower on this split), derivatives from a 400-harmonic Fourier fit at a "
          "detected 0.160 Hz with held torques, chosen by held-out evidence",
)


@dataclass(frozen=True)
class WrongLawCase:
    """A truth identified with a declared law that is not its own: ``oed identify`` must flag the channel."""

    name: str
    case: Case
    declared: str
    flagged: tuple[str, ...]
    xfail: str = ""


# the smooth Coulomb law of the simulator (tanh(dq / 0.05)) identified with the sign law
SIGN_LAW_ON_TANH = WrongLawCase(
    "sign law declared, tanh truth",
    Case("tanh truth", (TrueTerm(TanhCoulombFriction(joints=(1,)), (6.0,), (0.05,)),), named(("coulomb:tanh", "tau2"))),
    "viscous,coulomb",
    flagged=("tau2",),
)
