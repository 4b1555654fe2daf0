"""The robot as built, for ``oed identify`` and ``oed diagnose``: transmission, motor-side data, per-joint and
motor-side effects, rest segments, trivial predictors, the model's parameter vector, and the keys these add to
the verbs' documents (:func:`finish_document`).

Options (both verbs): ``transmission`` (a JSON file, :func:`dynamics.transmission_files.transmission_from_json`;
default: the URDF's <transmission> elements, or the built-in robot's: PUMA 560), ``joint_offsets`` (a JSON or CSV
file, :func:`dynamics.transmission_files.read_joint_offsets`: added to the recorded joint positions), ``min_speed`` (rows slower than
it, rad/s or m/s, are at rest) and ``rest`` (``drop``, the default, or ``smooth`` the Coulomb laws to
tanh(v / V)).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dynamics.effects.specs import build_effects
from dynamics.mjcf import is_mjcf, transmission_from_mjcf
from dynamics.measurements import Measurements
from dynamics.robot import RobotModel
from dynamics.robots import load_robot
from dynamics.simulation.joint_effects import is_puma560
from dynamics.transmission import (
    CouplingShapeError,
    JointDirections,
    Transmission,
    TransmissionError,
    UnknownJointError,
    puma560_transmission,
)
from dynamics.transmission_files import (
    read_joint_directions,
    read_joint_offsets,
    transmission_from_json,
    transmission_from_urdf,
)
from estimation.data.passive import passive_channels
from estimation.data.rest import check_min_speed, smooth_coulomb
from estimation.diagnosis.plain_laws import plain_model
from estimation.diagnosis.search import effect_channels
from dynamics.effects import Effect
from dynamics.models import IdentificationModel
from dynamics.runtime.progress import step
from estimation.identification.fit import IdentificationResult
from estimation.identification.friction_drift import FrictionDrift
from estimation.identification.joint_zeros import JointZeroCheck, check_joint_zeros
from estimation.identification.mount import MAX_SAMPLES as MOUNT_SAMPLES
from estimation.identification.mount import MOUNT_MARK, MountCheck, check_mount
from estimation.identification.model_parameters import model_parameters
from estimation.identification.prepared import PreparedRecords
from estimation.identification.trivial_predictors import trivial_mse, trivial_warnings
from oed.workflows.options import RecordOptions, model_has_shapes

if TYPE_CHECKING:  # the streamed path's, imported when it runs
    from estimation.streaming.description_checks import StreamedChecks


def resolve_transmission(args: RecordOptions, robot: RobotModel) -> Transmission | None:
    """``--transmission FILE``, else the URDF's, else the built-in robot's, else ``None``.

    With ``--joints N`` the transmission is read for the whole robot, then cut to its first ``N``
    motors (refused when one of them turns with a joint left out).
    """
    full = robot
    if getattr(args, "joints", None) is not None and (getattr(args, "transmission", None) or args.urdf is not None):
        full = load_robot(args.robot, urdf=args.urdf, joint_names=getattr(args, "joint_names", None),
                          locked_at=getattr(args, "locked_at", None))
    if getattr(args, "transmission", None):
        try:  # a file for the joints kept, or for the whole robot
            transmission = transmission_from_json(args.transmission, robot)
        except (CouplingShapeError, UnknownJointError) as error:
            if full is robot:
                raise
            try:
                transmission = transmission_from_json(args.transmission, full)
            except TransmissionError:
                raise error from None
    elif getattr(args, "urdf", None) is not None:  # a URDF's <transmission>, an MJCF's <actuator> gears
        transmission = (transmission_from_mjcf if is_mjcf(args.urdf) else transmission_from_urdf)(args.urdf, full)
    elif is_puma560(robot):
        transmission = puma560_transmission(robot.n_joints)
    else:
        transmission = None
    return None if transmission is None else transmission.truncated(robot.n_joints).check(robot)


def model_effects(args: RecordOptions, friction: str, robot: RobotModel,
                  transmission: Transmission | None) -> tuple[Any, ...]:
    """``friction`` (the ``--friction`` text without its delay) with per-joint, motor-side and combination items;
    smoothed with ``--rest smooth``."""
    effects = build_effects(friction, robot, transmission)
    if args.min_speed is not None:
        check_min_speed(args.min_speed)
        if args.rest == "smooth":
            effects = smooth_coulomb(effects, args.min_speed)
    return effects


def rest_records(records: PreparedRecords) -> dict[str, dict | None]:
    """What was dropped as at rest (``--min-speed`` with ``--rest drop``) from the training and validation records."""
    return {label: None if record is None or record.rest is None else record.rest.to_dict()
            for label, record in (("train", records.train), ("validation", records.validation))}


def rest_message(verb: str, records: dict[str, dict | None]) -> str | None:
    """How many rows at rest were dropped from each record, or ``None`` when none were."""
    parts = [f"{label} {record['dropped']} of {record['total']}" for label, record in records.items() if record]
    if not parts:
        return None
    speed = next(record["min_speed"] for record in records.values() if record)
    return f"rows at rest (slower than {speed:g}) dropped: " + ", ".join(parts)


def trivial_predictors(result: IdentificationResult, validate: Measurements | None,
                       chosen: Any = None) -> tuple[dict | None, tuple[str, ...]]:
    """Per-channel zero and nominal validation MSE of ``result``'s model, and the warnings where the model is
    worse: ``result``, or the ``chosen`` model's validation comparison when given (the answer the result holds)."""
    if validate is None or result.validation is None:
        return None, ()
    trivial = trivial_mse(result.model, validate)
    return trivial, trivial_warnings((result.validation if chosen is None else chosen).mse, trivial)


def finish_document(document: dict[str, Any], result: IdentificationResult, *, trivial: dict | None,
                    warnings: tuple[str, ...], rest: dict[str, dict | None], transmission: Transmission | None,
                    warnings_key: tuple[str, ...] = ("warnings",)) -> dict[str, Any]:
    """Add the new keys: ``validation.zero_mse``, ``validation.nominal_mse``, ``model_parameters``,
    ``rest``, ``transmission``; append the trivial-predictor warnings."""
    validation = document.get("validation")
    if trivial is not None and isinstance(validation, dict):
        validation.update({key: dict(value) for key, value in trivial.items()})
    document["model_parameters"] = model_parameters(result, transmission)
    document["rest"] = {label: record for label, record in rest.items() if record} or None
    document["transmission"] = None if transmission is None else {**transmission.to_dict(), "source": transmission.source}
    target = document
    for key in warnings_key[:-1]:
        target = target[key]
    target[warnings_key[-1]] = list(target.get(warnings_key[-1], [])) + list(warnings)
    return document


def worse_after(diagnosis: Any) -> tuple[str, ...]:
    """Channels whose validation MSE the diagnosis raised by more than 1 % (an added effect that
    helps the total but harms one channel); a passive joint's channel is not judged (its equation ``0 = Y_j θ`` is
    homogeneous: a fit meets it by parameters near zero, which is no better model)."""
    before = diagnosis.before.validation.mse if diagnosis.before.validation else {}
    after = diagnosis.after.validation.mse if diagnosis.after.validation else {}
    passive = passive_channels(diagnosis.after.model)  # 0 = Y_j θ is homogeneous: a fit can meet it by parameters
    # of the joint's bodies and friction near zero, which is no better model
    before = {channel: value for channel, value in before.items() if channel not in passive}
    return tuple(f"{channel}: the diagnosis raised its validation MSE from {before[channel]:.4g} to {after[channel]:.4g} "
                 f"({100 * (after[channel] / before[channel] - 1):.0f} % worse)"
                 for channel in before if channel in after and before[channel] > 0 and after[channel] > 1.01 * before[channel])


def resolve_joint_offsets(args: RecordOptions, robot: RobotModel) -> tuple[float, ...] | None:
    """``--joint-offsets FILE`` read for ``robot`` (:func:`dynamics.transmission_files.read_joint_offsets`), or
    ``None``."""
    path = getattr(args, "joint_offsets", None)
    return None if path is None else read_joint_offsets(path, robot)


def resolve_joint_directions(args: RecordOptions, robot: RobotModel) -> JointDirections | None:
    """The joints' directions of ``--joint-offsets FILE`` (its ``signs`` and ``torque_signs``:
    :func:`dynamics.transmission_files.read_joint_directions`), or ``None`` (none reversed, or no file)."""
    path = getattr(args, "joint_offsets", None)
    return None if path is None else read_joint_directions(path, robot)


def joint_zero_notes(model: IdentificationModel, train: Measurements, validation: Measurements | None, *,
                     delay: Any = None) -> tuple[str, ...]:
    """The warning that the recorded joint positions look offset from the description's zeros, when a constant
    offset per joint lowers the held-out error markedly (:func:`estimation.identification.joint_zeros.check_joint_zeros`:
    ``validation``, or the second half of ``train``); none with a delay search or shaped laws (fitted by a search
    each: the check refits the plain columns only)."""
    if delay is not None or model_has_shapes(model):
        return ()
    with step("joint zeros checked against the description's"):
        check = check_joint_zeros(model, train, validation, warn=False)
    return () if check is None or not check.marked else (check.message(model.robot.joint_names),)


def description_checks(model: IdentificationModel, train: Measurements, validation: Measurements | None, *,
                       delay: Any = None) -> tuple[JointZeroCheck | None, MountCheck | None]:
    """The joint-zero check and the mount check of ``oed identify``, each when it marks and is the one said
    (:func:`competing_checks`): a robot on a wall, on the ceiling, off level, whose URDF gives no mount has another
    direction of gravity predict the validation record with at most half the error
    (:func:`estimation.identification.mount.check_mount`). The mount is not checked without a validation record, with
    a delay search or shaped laws."""
    if delay is not None or model_has_shapes(model):
        return None, None
    zeros = marked_joint_zeros(model, train, validation)
    mount = None
    if validation is not None:
        with step("gravity's direction checked against the description's"):
            mount = check_mount(model, train, validation)
    mount = None if mount is None or not mount.marked else mount
    return competing_checks(zeros, mount)


def description_notes(model: IdentificationModel, checks: tuple[JointZeroCheck | None, MountCheck | None], *,
                      gravity_taken: bool = False, subtracted: bool = False) -> tuple[str, ...]:
    """The warnings of :func:`description_checks` (``checks``): the joints' zeros or directions, the torques' gravity
    load pointing elsewhere than the description says (``gravity_taken``: the answer was fitted with the found
    gravity, ``subtracted``: to the torques with the description's gravity torque added back,
    :mod:`estimation.consistent.mounted_gravity`)."""
    zeros, mount = checks
    return said_description(model, zeros, mount, None if mount is None
                            else mount.message(taken=gravity_taken, subtracted=subtracted))


def competing_checks(zeros: JointZeroCheck | None, mount: MountCheck | None
                     ) -> tuple[JointZeroCheck | None, MountCheck | None]:
    """The marked joint-zero and mount checks, the one that predicts the validation record with the less error kept
    when both mark (the other ``None``): a reversed torque flips its joint's gravity load, and a turned gravity moves
    every joint's as an offset would, so each check can take up the other's fault."""
    if zeros is not None and mount is not None:
        if mount.said_mse / mount.declared_mse < zeros.total_ratio:
            return None, mount
        return zeros, None
    return zeros, mount


def marked_joint_zeros(model: IdentificationModel, train: Measurements, validation: Measurements | None, *,
                       delay: Any = None) -> JointZeroCheck | None:
    """The joint-zero check (:func:`estimation.identification.joint_zeros.check_joint_zeros`) when it marks, else
    ``None``; not checked with a delay search or shaped laws (:func:`joint_zero_notes`)."""
    if delay is not None or model_has_shapes(model):
        return None
    with step("joint zeros checked against the description's"):
        zeros = check_joint_zeros(model, train, validation, warn=False)
    return None if zeros is None or not zeros.marked else zeros


def said_description(model: IdentificationModel, zeros: JointZeroCheck | None, mount: MountCheck | None,
                     mount_said: str | None) -> tuple[str, ...]:
    """The warnings of the marked joint-zero and mount checks (``mount_said``: the mount's sentence): a reversed
    torque flips its joint's gravity load, and a turned gravity moves every joint's as an offset would, so each check
    can take up the other's fault: when both mark, the one that predicts the validation record with the less error
    is said (the other's sentence not)."""
    zeros, kept = competing_checks(zeros, mount)
    mount_said = None if kept is None else mount_said
    return ((() if zeros is None else (zeros.message(model.robot.joint_names),))
            + (() if mount_said is None else (mount_said,)))


#: the candidates of the diagnosis that a load of the joint's position alone can pass for, as a turned gravity's
POSITION_LAWS = ("spring", "ripple")
#: the samples of each record the diagnosis's mount check sums (evenly spaced: a gravity load changes with the
#: positions only, slowly; ``oed identify`` takes :data:`estimation.identification.mount.MAX_SAMPLES`)
DIAGNOSIS_MOUNT_SAMPLES = 1000


def diagnosis_mount(model: IdentificationModel, train: Measurements, validation: Measurements | None, *,
                    delay: Any = None) -> MountCheck | None:
    """The mount check of ``oed diagnose``, run before its search (:func:`estimation.identification.mount.check_mount`
    on the plain model of the declared one, :func:`estimation.diagnosis.plain_laws.plain_model`: the diagnosis's
    declared model often lacks the friction laws and offsets the search then adds, whose absence would hide the
    gravity load): the check when it marks, else ``None``; not checked without a validation record, with a delay
    search or shaped laws (as :func:`description_notes`)."""
    if validation is None or delay is not None or model_has_shapes(model):
        return None
    with step("gravity's direction checked against the description's"):
        check = check_mount(plain_model(model), train, validation, samples=DIAGNOSIS_MOUNT_SAMPLES)
    return check if check is not None and check.marked else None


def mount_candidates(model: IdentificationModel, candidates: Sequence[Effect], mount: MountCheck | None
                     ) -> tuple[Effect, ...]:
    """The diagnosis's candidates without the laws of a joint's position alone (:data:`POSITION_LAWS`: a spring, a
    position ripple) on the channels whose load the found gravity explains (their validation error with it at most
    :data:`estimation.identification.mount.MOUNT_MARK` of the description's,
    :meth:`~estimation.identification.mount.MountCheck.explained_channels`); ``candidates`` when ``mount`` is
    ``None``. The description's gravity is kept (the description is the user's): the turned gravity's load stays in
    the residual, and a spring there would name an effect the robot does not have (h-mountdiag,
    ``benchmarks/README.md``)."""
    if mount is None:
        return tuple(candidates)
    explained = {model.channels[index] for index in mount.explained_channels()}  # the plain model's channels
    return tuple(effect for effect in candidates
                 if effect.name not in POSITION_LAWS or not set(effect_channels(effect, model)) <= explained)


def diagnosis_mount_notes(model: IdentificationModel, zeros: JointZeroCheck | None, mount: MountCheck | None, *,
                          gravity_taken: bool = False, subtracted: bool = False) -> tuple[str, ...]:
    """The diagnosis's warnings of the marked joint-zero and mount checks (:func:`said_description`: the one that
    predicts the validation record better when both mark), the mount's saying which joints the search tried without
    the laws of their position (:func:`mount_candidates`); when the joints' zeros or directions are said instead,
    a sentence still says what the search left out. ``gravity_taken``: the answer is the diagnosis with the found
    gravity (:mod:`estimation.consistent.mounted_gravity`), whose search tried every law."""
    channels = () if mount is None else mount.explained_channels()
    names = ", ".join(model.channels[index] for index in channels)
    shares = ", ".join(f"{model.channels[index]} "
                       f"{1.0 - mount.said_channel_mse[index] / mount.declared_channel_mse[index]:.0%}"
                       for index in channels)
    said = None if mount is None else mount.message(taken=gravity_taken, subtracted=subtracted) \
        if not channels or gravity_taken or subtracted else (
        f"{mount.message()}; the diagnosis keeps it too, and tries no spring or position ripple on {names}, whose "
        f"validation error the found gravity lowers by {1.0 - MOUNT_MARK:.0%} or more ({shares}): their "
        "position-dependent load is gravity's (turned, or absent from the torques)")
    notes = said_description(model, zeros, mount, said)
    if said is not None and said not in notes and channels and not gravity_taken and not subtracted:
        notes += (f"the diagnosis tried no spring or position ripple on {names}: another direction of gravity "
                  f"explains their load as well ({shares} less validation error), though the joints' zeros or "
                  "directions said explain the records better",)
    return notes


def streamed_joint_zero_notes(model: IdentificationModel, train: Sequence[str | Path], train_samples: int,
                              held_out: Sequence[str | Path], held_out_samples: int, *,
                              options: Mapping[str, Any]) -> tuple[str, ...]:
    """:func:`joint_zero_notes` of records read in blocks (``train`` and ``held_out``: their files, with their
    counts of prepared samples; ``options``: how the streamed fit prepared them,
    :func:`estimation.streaming.periods.plan_chunks`' keywords), on the samples the in-memory check keeps
    (:func:`estimation.streaming.joint_zeros.streamed_joint_zeros`): one more pass over the files. None with shaped
    laws."""
    zeros = streamed_marked_joint_zeros(model, train, train_samples, held_out, held_out_samples, options=options)
    return () if zeros is None else (zeros.message(model.robot.joint_names),)


def streamed_marked_joint_zeros(model: IdentificationModel, train: Sequence[str | Path], train_samples: int,
                                held_out: Sequence[str | Path], held_out_samples: int, *,
                                options: Mapping[str, Any]) -> JointZeroCheck | None:
    """The joint-zero check of records read in blocks (:func:`streamed_joint_zero_notes`) when it marks, else
    ``None``."""
    if model_has_shapes(model):
        return None
    from estimation.streaming.joint_zeros import streamed_joint_zeros  # the streamed path's: imported when it runs

    with step("joint zeros checked against the description's (a pass over the files)"), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the files' findings were said when the fit read them
        check = streamed_joint_zeros(model, train, train_samples, held_out, held_out_samples, options=options)
    return None if check is None or not check.marked else check


def streamed_checks(model: IdentificationModel, train: Sequence[str | Path], train_samples: int,
                    validate: Sequence[str | Path], validate_samples: int, *, options: Mapping[str, Any],
                    mount_model: IdentificationModel | None, mount_samples: int,
                    drift_model: IdentificationModel | None) -> StreamedChecks:
    """The mount check of ``mount_model`` and the friction-drift check of ``drift_model`` (each when given) of
    records read in blocks, on the samples the in-memory checks keep
    (:func:`estimation.streaming.description_checks.streamed_description_checks`: one more pass over the files; on
    the Fourier path the samples memory prepares too: a file's averaged period, or its every sample with the fit's
    motion)."""
    from estimation.streaming.description_checks import StreamedChecks, streamed_description_checks  # when it runs

    if not validate or (mount_model is None and drift_model is None):
        return StreamedChecks()
    with step("gravity's direction and the friction checked against the description's and the training record's "
              "(a pass over the files)"), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the files' findings were said when the fit read them
        return streamed_description_checks(model, train, train_samples, validate, validate_samples, options=options,
                                           mount_model=mount_model, mount_samples=mount_samples,
                                           drift_model=drift_model)


@dataclass(frozen=True)
class StreamedFindings:
    """What ``oed identify``'s checks of the description and of the friction found on records read in blocks
    (:func:`streamed_description_findings`): the joint-zero and mount checks when they mark (``None`` else), the
    friction-drift check (``None``: not checked)."""

    zeros: JointZeroCheck | None = None
    mount: MountCheck | None = None
    friction_drift: FrictionDrift | None = None

    @property
    def said_mount(self) -> MountCheck | None:
        """The mount when it is the check said (:func:`competing_checks`): the gravity candidate of the answer, as
        :func:`description_checks`' in memory."""
        return competing_checks(self.zeros, self.mount)[1]


def streamed_description_findings(model: IdentificationModel, train: Sequence[str | Path], train_samples: int,
                                  validate: Sequence[str | Path], validate_samples: int, *,
                                  options: Mapping[str, Any]) -> StreamedFindings:
    """The joint-zero check (:func:`streamed_marked_joint_zeros`), the mount check and the friction drift of the
    declared model (:func:`streamed_checks`) of records read in blocks, on the samples memory checks. None with
    shaped laws."""
    zeros = streamed_marked_joint_zeros(model, train, train_samples, validate, validate_samples, options=options)
    if model_has_shapes(model):
        return StreamedFindings(zeros)
    checks = streamed_checks(model, train, train_samples, validate, validate_samples, options=options,
                             mount_model=model, mount_samples=MOUNT_SAMPLES, drift_model=model)
    mount = None if checks.mount is None or not checks.mount.marked else checks.mount
    return StreamedFindings(zeros, mount, checks.friction_drift)


def streamed_description_notes(model: IdentificationModel, train: Sequence[str | Path], train_samples: int,
                               validate: Sequence[str | Path], validate_samples: int, *,
                               options: Mapping[str, Any], findings: StreamedFindings | None = None,
                               gravity_taken: bool = False, subtracted: bool = False
                               ) -> tuple[tuple[str, ...], FrictionDrift | None]:
    """``oed identify``'s :func:`description_notes` and friction-drift check of records read in blocks
    (:func:`streamed_description_findings`, or its ``findings`` already made), said as in memory
    (:func:`said_description`, then the drift's warning; ``gravity_taken``: the answer was fitted with the found
    gravity; ``subtracted``: to the torques with the description's gravity torque added back, ``options["load"]``,
    on which the drift is then checked again, as memory checks it on the answer's records); and the drift check
    (``None``: not checked). None with shaped laws."""
    if findings is None:
        findings = streamed_description_findings(model, train, train_samples, validate, validate_samples,
                                                 options=options)
    mount = findings.mount
    notes = said_description(model, findings.zeros, mount,
                             None if mount is None else mount.message(taken=gravity_taken, subtracted=subtracted))
    drift = findings.friction_drift
    if subtracted and drift is not None:  # on the records the answer holds: the log with the load added back
        drift = streamed_checks(model, train, train_samples, validate, validate_samples, options=options,
                                mount_model=None, mount_samples=MOUNT_SAMPLES, drift_model=model).friction_drift
    said = None if drift is None else drift.message()
    return (notes if said is None else (*notes, said)), drift
