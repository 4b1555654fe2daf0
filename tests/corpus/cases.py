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

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.linear import Armature, CoulombFriction, DirectionalViscousFriction, JointOffset, Spring
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
class ExoticTerm:
    """A true torque of a form no candidate family holds (a test-only truth): ``law(q_j, dq_j, t)`` added on joint
    ``joint``'s channel. ``holds``: the candidate specs the truth may be said to hold on that channel (the Coulomb-like
    part of a friction law, say); any other effect named there, or anywhere else, is a false effect."""

    name: str
    joint: int
    law: Callable[[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]
    holds: tuple[str, ...] = ()


@dataclass(frozen=True)
class Case:
    """A simulated case and the outcome the diagnosis loop must reach on it (module docstring)."""

    name: str
    terms: tuple[TrueTerm, ...]
    named: frozenset[tuple[str, str]]
    exotic: tuple[ExoticTerm, ...] = ()
    above_floor: tuple[str, ...] = ()
    derivatives: Literal["given", "positions"] = "given"
    delay: float = 0.0
    floor_tolerance: float = 1.5
    xfail: str = ""
    slow: bool = False
    seeds: tuple[int, int] = (3, 4)
    repeat: bool = False  # the validation record repeats the training motion (other noise)
    rate_hz: float = 250.0  # samples per second (two 5 s periods a record)

    def __post_init__(self) -> None:
        if self.derivatives not in ("given", "positions"):
            raise ValueError(f"case {self.name}: derivatives must be 'given' or 'positions', got {self.derivatives!r}")

    @property
    def known_law_tolerance(self) -> float:
        return KNOWN_LAW_GIVEN if self.derivatives == "given" else KNOWN_LAW_POSITIONS

    @property
    def allowed(self) -> frozenset[tuple[str, str]]:
        """What may be named beside ``named``: what the exotic truths hold on their channels."""
        return frozenset((spec, f"tau{term.joint + 1}") for term in self.exotic for spec in term.holds)


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

VISCOUS_BY_DIRECTION = Case("viscous by direction, tau2", (TrueTerm(DirectionalViscousFriction(joints=(1,)), (2.0,)),),
                            named(("viscous:direction", "tau2")))

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
    # viscous friction differing by direction: 2 |dq| beside the declared fv dq (slopes fv + 2 and fv - 2)
    VISCOUS_BY_DIRECTION,
    # Coulomb levels differing by direction on joints 1 and 3 (a sign law and an offset: 5 and 3, 3 and 2 N m), a
    # symmetric sign law on joint 2, every viscous law symmetric: nothing of the direction law named
    Case("coulomb levels by direction, viscous symmetric",
         (TrueTerm(CoulombFriction(), (4.0, 9.0, 2.5)), TrueTerm(JointOffset(joints=(0, 2)), (1.0, 0.5))),
         named(("coulomb", "tau1"), ("coulomb", "tau2"), ("coulomb", "tau3"), ("offset", "tau1"), ("offset", "tau3")),
         slow=True),
)

#: measured on the code of the day, where a case from positions only misses its targets
POSITIONS_XFAIL: dict[str, str] = {}  # none: the sign law from positions reaches its floor (0.99/0.99/0.98)
POSITIONS: tuple[Case, ...] = tuple(
    positions_only(case, xfail=POSITIONS_XFAIL.get(case.name, "")) for case in ALONE + PAIRS[:3] + (VISCOUS_BY_DIRECTION,)
    if case.name != "coupled coulomb q2+q3"
)

CASES: tuple[Case, ...] = ALONE + PAIRS + NON_DEFAULT + POSITIONS


@dataclass(frozen=True)
class LoopCase:
    """A user's loop through the CLI on files, and its targets (see :mod:`tests.corpus.test_user_loops`): ``named``
    exactly, or any set in ``also`` (the same physics in other laws), and besides what ``allowed`` lets be named."""

    name: str
    named: frozenset[tuple[str, str]]
    floor_tolerance: float | None = 1.5
    after_over_before: float | None = None
    xfail: str = ""
    also: tuple[frozenset[tuple[str, str]], ...] = ()
    allowed: frozenset[tuple[str, str]] = frozenset()


# the simulator's Coulomb law is tanh(dq / 0.05): the sign law or the tanh law names it
COULOMB_LIKE = "coulomb|coulomb:tanh"
README_LOOP = LoopCase(
    "README loop",
    named(*((family, f"tau{joint}") for joint in (1, 2, 3) for family in (COULOMB_LIKE, "offset"))),
)
# EMPS's friction is asymmetric: the published IDIM-LS model (Script_IDIM_LS_Asym_Fric.m beside the symmetric one;
# Fc 20.4 N, offset -3.16 N) is a Coulomb law whose levels differ with the direction, Fc·sign(dq) + offset while
# moving. The shifted sigmoid is that law in one smooth term: at 74a5e1a the loop names sigmoid@tau1 (phi1 43.93,
# phi2 207.6 s/m, phi3 1.45 mm/s: Fc = phi1/2 = 22.0 N, offset while moving -phi1/2 tanh(phi2 phi3/2) = -3.29 N)
# and delay@tau1 (-1.44 ms), after/before 0.253 on DATA_EMPS_PULSES (a repeat of the training motion). On a record
# no choice saw (h-xfail3: trained on DATA_EMPS's first two thirds, validated on its last third, tested on
# DATA_EMPS_PULSES as benchmarks/bench_real_robots.py splits it), test MSE in N²: viscous,coulomb,offset 47.72;
# viscous,sigmoid 47.09; viscous,sigmoid,delay 45.48 (the diagnosis's answer, 0.497 of the plain fit);
# viscous,coulomb:tanh,offset 47.54; viscous,coulomb,offset,delay 49.83: the sigmoid is no false effect. Either
# description is accepted, a delay beside it allowed. (Until 74a5e1a this case was a strict xfail measured at
# 7cfacee on a 400-harmonic Fourier fit: after/before 0.786 at 0.99x the validation record's period-to-period
# floor, 332 N², which counts the response to the pulses as noise: DATA_EMPS's, the same motion without them, is
# 0.16 N²; the floor from differences is 0.023 N². The 0.3 is reachable, and reached.)
EMPS_LOOP = LoopCase(
    "EMPS, no flags",
    named(("sigmoid", "tau1")),
    floor_tolerance=None,
    after_over_before=0.3,
    also=(named((COULOMB_LIKE, "tau1"), ("offset", "tau1")),),
    allowed=named(("delay", "tau1")),
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


# truths outside the candidate families (test-only laws): the diagnosis may name what they hold, nothing else, and
# must say where the residual stays above the floor
COULOMB_LIKE_LAWS = ("coulomb", "coulomb:tanh", "sigmoid")  # the sigmoid: a Coulomb law, asymmetric over the motion


def dahl(fc: float, stiffness: float) -> Callable[..., NDArray[np.float64]]:
    """Dahl's friction (1968): ``dF/dx = σ (1 − sign(dx) F / fc)`` along the joint's path ``x = q``, a hysteresis
    whose steady state is Coulomb friction ``fc sign(dq)``, integrated exactly step by step from the state the
    periodic record ends in (so that the record is periodic in it)."""

    def law(q: NDArray[np.float64], dq: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
        steps = np.diff(q, prepend=q[0])
        force, out = 0.0, np.empty_like(q)
        for _ in range(2):  # the second pass starts where the first ended
            for index, step in enumerate(steps):
                target = fc * np.sign(step) if step else force
                force = target + (force - target) * np.exp(-stiffness * abs(step) / fc)
                out[index] = force
        return out

    return law


def position_dependent_coulomb(fc: float, depth: float, n: float) -> Callable[..., NDArray[np.float64]]:
    """Coulomb friction whose level varies along the joint's travel, ``fc (1 + depth sin(n q)) tanh(dq / 0.02)``
    (a worn or eccentric gear): neither a plain law nor a ripple, which does not change sign with the motion."""

    def law(q: NDArray[np.float64], dq: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
        return fc * (1.0 + depth * np.sin(n * q)) * np.tanh(dq / 0.02)

    return law


def exponential_stribeck(fc: float, fs: float, vs: float) -> Callable[..., NDArray[np.float64]]:
    """Stribeck's law with the exponent 1, ``(fc + fs exp(−|dq|/vs)) sign(dq)``: the candidate ``stribeck:velocity``
    holds the Gaussian form (exponent 2) only."""

    def law(q: NDArray[np.float64], dq: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
        return (fc + fs * np.exp(-np.abs(dq) / vs)) * np.sign(dq)

    return law


def play_friction(level: float, half_width: float) -> Callable[..., NDArray[np.float64]]:
    """Prandtl's elastic-plastic friction: ``k (q − p(q))``, ``p`` the play (backlash) operator of half-width
    ``half_width`` along the joint's path, ``k = level / half_width``: a stiff spring for ``half_width`` after each
    reversal, then ``level`` against the motion; run twice over the record so that it starts in the state it ends
    in. A hysteresis with a corner where Dahl's law is smooth."""

    def law(q: NDArray[np.float64], dq: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
        out, p = np.empty_like(q), q[0]
        for _ in range(2):
            for index, value in enumerate(q):
                p = min(max(p, value - half_width), value + half_width)
                out[index] = level / half_width * (value - p)
        return out

    return law


def warming_coulomb(fc: float, excess: float, seconds: float) -> Callable[..., NDArray[np.float64]]:
    """Coulomb friction warming over each record: ``fc (1 + excess exp(−t / T)) tanh(dq / 0.02)``, the level
    ``1 + excess`` times the warm one at the record's start (a joint switched on cold): no law of the velocity and
    the position holds a level that drifts with time."""

    def law(q: NDArray[np.float64], dq: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
        return fc * (1.0 + excess * np.exp(-(t - t[0]) / seconds)) * np.tanh(dq / 0.02)

    return law


def tight_spot(fc: float, rise: float, where: float, width: float) -> Callable[..., NDArray[np.float64]]:
    """Coulomb friction ``fc`` with a tight spot: ``rise`` more within a Gaussian of ``width`` rad about ``where``
    (a dent in a bearing's race): ``(fc + rise exp(−(q − where)² / 2 width²)) tanh(dq / 0.02)``."""

    def law(q: NDArray[np.float64], dq: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
        return (fc + rise * np.exp(-0.5 * ((q - where) / width) ** 2)) * np.tanh(dq / 0.02)

    return law


def fine_cogging(amplitude: float, periods: float) -> Callable[..., NDArray[np.float64]]:
    """A cogging ripple of ``periods`` a radian, ``amplitude sin(periods q + 0.4)``: beyond the 60 a radian the
    ripple family offers (a motor's cogging seen through a gear)."""

    def law(q: NDArray[np.float64], dq: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
        return amplitude * np.sin(periods * q + 0.4)

    return law


OUTSIDE: tuple[Case, ...] = (
    # a hysteresis: on joint 2's short travel (0.38 rad) more a stiff spring at each reversal than a Coulomb law
    Case("dahl, tau2", (), named(), exotic=(ExoticTerm("dahl", 1, dahl(6.0, 150.0), COULOMB_LIKE_LAWS),),
         above_floor=("tau2",)),
    Case("dahl, tau2, validation repeats the motion", (), named(),
         exotic=(ExoticTerm("dahl", 1, dahl(6.0, 150.0), COULOMB_LIKE_LAWS),), above_floor=("tau2",), repeat=True),
    Case("position-dependent coulomb, tau3", (), named(),
         exotic=(ExoticTerm("position-dependent coulomb", 2, position_dependent_coulomb(3.0, 0.6, 3.0),
                            COULOMB_LIKE_LAWS),), above_floor=("tau3",)),
    Case("position-dependent coulomb, tau3, validation repeats the motion", (), named(),
         exotic=(ExoticTerm("position-dependent coulomb", 2, position_dependent_coulomb(3.0, 0.6, 3.0),
                            COULOMB_LIKE_LAWS),), above_floor=("tau3",), repeat=True),
    Case("exponential stribeck, tau3", (), named(),
         exotic=(ExoticTerm("exponential stribeck", 2, exponential_stribeck(2.0, 3.0, 0.1),
                            COULOMB_LIKE_LAWS + ("stribeck:velocity",)),), above_floor=("tau3",)),
    Case("exponential stribeck on every joint", (), named(),
         exotic=tuple(ExoticTerm("exponential stribeck", joint, exponential_stribeck(fc, fs, vs),
                                 COULOMB_LIKE_LAWS + ("stribeck:velocity",))
                      for joint, fc, fs, vs in ((0, 3.0, 2.0, 0.15), (1, 5.0, 3.0, 0.3), (2, 2.0, 3.0, 0.2))),
         above_floor=("tau1", "tau2", "tau3")),
    # the truths (sigmoid, Stribeck on every joint), confirmed on a repeat of the training motion
    Case("sigmoid on every joint, validation repeats the motion",
         tuple(TrueTerm(SigmoidFriction(joints=(joint,)), (height,), (slope, shift))
               for joint, height, slope, shift in ((0, 6.0, 30.0, 0.1), (1, 8.0, 40.0, 0.15), (2, 3.0, 60.0, -0.05))),
         named(("sigmoid", "tau1"), ("sigmoid", "tau2"), ("sigmoid", "tau3")), repeat=True),
    Case("stribeck, validation repeats the motion", (STRIBECK,), named(("stribeck:velocity", "tau3")), repeat=True),
)
#: the plants of h-plants19 (``tests/test_outside_family_plants.py`` runs them through the command line): truths no
#: family holds, each on one joint; slow beyond the first (each about 5 s)
OUTSIDE_PLANTS: tuple[Case, ...] = (
    Case("elastic-plastic play, tau2", (), named(),
         exotic=(ExoticTerm("play", 1, play_friction(4.0, 0.01), COULOMB_LIKE_LAWS),), above_floor=("tau2",)),
    Case("coulomb warming over each record, tau2", (), named(),
         exotic=(ExoticTerm("warming coulomb", 1, warming_coulomb(4.0, 0.6, 3.0), COULOMB_LIKE_LAWS),),
         above_floor=("tau2",), slow=True),
    Case("tight spot, tau3", (), named(),
         exotic=(ExoticTerm("tight spot", 2, tight_spot(2.0, 3.0, 0.0, 0.04), COULOMB_LIKE_LAWS),),
         above_floor=("tau3",), slow=True),
    Case("cogging at 85 periods a radian, tau1", (), named(),
         exotic=(ExoticTerm("fine cogging", 0, fine_cogging(0.5, 85.0)),), above_floor=("tau1",), slow=True),
)


def _long_xfail() -> dict[str, str]:
    """Measured on the code of the day, where a 1 kHz case misses its targets (none now: the issue's Stribeck truth
    on every joint passes since a non-physical local optimum of a shaped law gives way to a better physical one,
    :func:`estimation.diagnosis.candidates.trials.better_physical_optimum`)."""
    return {}


#: the same truths, the derivatives made from the positions as a user gets them (slow)
OUTSIDE_POSITIONS: tuple[Case, ...] = tuple(positions_only(case) for case in OUTSIDE)
#: longer records (1 kHz, 10 000 samples each), where more power lets an approximation pass more tests (slow)
OUTSIDE_LONG: tuple[Case, ...] = tuple(
    Case(**{**{key: getattr(case, key) for key in Case.__dataclass_fields__},
            "name": f"{case.name}, 1 kHz", "rate_hz": 1000.0, "slow": True,
            "xfail": _long_xfail().get(case.name, "")})
    for case in OUTSIDE + NON_DEFAULT[1:2] if not case.repeat)

