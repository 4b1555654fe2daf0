"""Where the sagging arm's test error comes from, and what a joint-compliance law would give (h-compliance).

The case of ``tests/test_unseen_robot_days.py`` (a UR10e-like arm, the shoulder's and the elbow's encoders on the
motors: the logged angle the link's plus its torque over a stiffness ``k``, 0.5 degrees at the training record's
largest load; Fourier training and validation, a point-to-point test with rests). On the plain least-squares class of
``benchmarks/bench_real_robots.py`` (rigid body, viscous, Coulomb, offset; its cut-off chosen on the validation
record), this prints each joint's test MSE:

- on the logged angles (the reference of the test), on the links' angles (what the deflection costs: the floor of
  any compliance law), and the torque noise floor;
- with a compliance law ``q_link = q - tau / k`` per joint: ``c = 1/k`` fitted with ``theta`` by damped
  Gauss-Newton steps (the step halved until the training error falls; the column of ``c_j`` is
  ``-(d(Y theta)/d q_j) tau_j`` at the corrected angle, ``tau`` the model's own torque); a record predicted by the
  fixed point ``tau = Y(q - c tau) theta`` from the rigid prediction, in the training's fit as in a prediction
  (the measured torque never enters the regressor: it would partly fit itself);
- three adoption rules, each against the validation record (no fit used it) by the paired difference of the total
  MSE over 10 contiguous blocks (1.96 standard errors; the diagnosis's measured gain takes 2 of 5 blocks, on the
  mean log score over the channels), a law kept only with
  every stiffness positive: forward selection (a joint at a time, every law taken refitted with the new one);
  backward elimination from every joint whose column is not zero; and the joints' laws as one decision (those
  with a positive stiffness together against none, then each member whose removal does not raise the
  validation error dropped);
- the same on the rigid truth (the links' angles logged), where no law should be adopted.

``--robot puma``: the PUMA's 6 joints sagging alike (10 s / 4 s / 8 s at 250 Hz, no dq, a point-to-point test).

Run: ``.venv/bin/python -m tests.compliance_trace [--robot ur10e|puma]`` (a script beside the tests, which it
imports; not collected by pytest; several minutes on two shared cores).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.bench_real_robots import PlainFit, filtered_motion
from tests.test_unseen_robot_days import DAYS, logs, sagging
from tests.test_unseen_robot_labs import Lab, puma, write_records

BLOCKS, TIED_SE = 10, 1.96


class CompliantPlainFit:
    """The plain class at one cut-off, with a compliance ``c`` (rad per N m) per joint."""

    def __init__(self, plain: PlainFit, cutoff_hz: float) -> None:
        self.plain, self.cutoff = plain, cutoff_hz

    def regressor(self, q, dq, ddq):
        return self.plain.stacked(q, dq, ddq)[:, :, self.plain.columns]

    def fit(self, record, c, iterations: int = 2):
        """``theta`` of the plain class on the training record's angles corrected by ``c`` times the model's own
        torque (the fixed point of :meth:`predict`, refitted ``iterations`` times from the rigid fit), never the
        measured one: a regressor holding the measured torque would partly fit the torque by itself."""
        keep = self.plain.kept(record, self.cutoff)
        q, dq, ddq, tau = filtered_motion(record, self.cutoff)
        Y = self.regressor(q, dq, ddq)[keep]
        theta = np.linalg.lstsq(Y.reshape(-1, Y.shape[2]), tau[keep].reshape(-1), rcond=None)[0]
        for _ in range(iterations if np.any(c) else 0):
            Y = self.regressor(q - c * self.predict(record, c, theta), dq, ddq)[keep]
            theta = np.linalg.lstsq(Y.reshape(-1, Y.shape[2]), tau[keep].reshape(-1), rcond=None)[0]
        return theta

    def predict(self, record, c, theta, iterations: int = 2):
        """The fixed point ``tau = Y(q - c tau, dq, ddq) theta`` from the rigid prediction (the record's torques
        unused)."""
        q, dq, ddq, _ = filtered_motion(record, self.cutoff)
        predicted = self.regressor(q, dq, ddq) @ theta
        for _ in range(iterations if np.any(c) else 0):
            predicted = self.regressor(q - c * predicted, dq, ddq) @ theta
        return predicted

    def residual(self, record, c, theta):
        keep = self.plain.kept(record, self.cutoff)
        return (record.tau - self.predict(record, c, theta))[keep]

    def gauss_newton(self, record, joints, steps: int = 3, eps: float = 1e-4, halvings: int = 8):
        """``c`` on ``joints`` and ``theta`` from ``c = 0``: each step solves ``theta`` and ``dc`` together on the
        linearised model, then refits ``theta`` on the corrected angles; the step halved until the training
        error (at the refitted ``theta``) falls (damped Gauss-Newton), none taken when no halving lowers it."""
        n = record.q.shape[1]
        keep = self.plain.kept(record, self.cutoff)
        q, dq, ddq, tau = filtered_motion(record, self.cutoff)

        def training(c_trial):
            theta_trial = self.fit(record, c_trial)
            residual = tau[keep] - self.predict(record, c_trial, theta_trial)[keep]
            return float(np.sum(residual**2)), theta_trial

        c = np.zeros(n)
        error, theta = training(c)
        for _ in range(steps):
            model_torque = self.predict(record, c, theta)
            Y = self.regressor(q - c * model_torque, dq, ddq)
            base = Y @ theta
            columns = []
            for joint in joints:
                shifted = q - c * model_torque
                shifted[:, joint] -= eps * model_torque[:, joint]
                columns.append(((self.regressor(shifted, dq, ddq) @ theta - base) / eps)[keep].reshape(-1))
            A = np.column_stack([Y[keep].reshape(-1, Y.shape[2]), *columns])
            step = np.zeros(n)
            step[list(joints)] = np.linalg.lstsq(A, tau[keep].reshape(-1), rcond=None)[0][Y.shape[2]:]
            for _ in range(halvings):
                trial_error, trial_theta = training(c + step)
                if trial_error < error:
                    c, error, theta = c + step, trial_error, trial_theta
                    break
                step = step / 2
            else:
                break
        return c, theta


def still_columns(fit: CompliantPlainFit, record, theta) -> list[int]:
    """The joints whose compliance column is zero on ``record`` (no gravity or inertia varies with their angle)."""
    q, dq, ddq, tau = filtered_motion(record, fit.cutoff)
    base = fit.regressor(q, dq, ddq) @ theta
    still = []
    for joint in range(q.shape[1]):
        shifted = q.copy()
        shifted[:, joint] -= 1e-4 * tau[:, joint]
        if np.max(np.abs(fit.regressor(shifted, dq, ddq) @ theta - base)) < 1e-9:
            still.append(joint)
    return still


def paired(candidate: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """Total validation MSE difference (candidate less reference) and its standard error over contiguous blocks."""
    difference = (candidate**2).sum(axis=1) - (reference**2).sum(axis=1)
    blocks = np.array([block.mean() for block in np.array_split(difference, BLOCKS)])
    return float(difference.mean()), float(np.std(blocks, ddof=1) / np.sqrt(BLOCKS))


def lab_of(robot: str) -> Lab:
    """The xfail's lab (``ur10e``), or the PUMA's 6 joints in the same sagging (10 s / 4 s / 8 s at 250 Hz, no dq,
    a point-to-point test)."""
    if robot == "ur10e":
        return next(day for day in DAYS if "sagging" in day.name).lab
    return Lab("PUMA 6 joints sagging", puma(6), *logs(), test_motion="point-to-point")


def records_of(folder: Path, logged: bool, robot: str = "ur10e"):
    lab = lab_of(robot)
    urdf, records, files, spread = write_records(lab, folder)
    link = dict(records)
    if logged:
        logger = sagging()
        for role, path in files.items():
            _, records[role] = logger(role, pd.read_csv(path), records[role])
    return urdf, records, link, (0.02 * spread) ** 2, min(log.rate_hz for log in (lab.train, lab.validate, lab.test))


def traced(folder: Path, logged: bool, robot: str = "ur10e") -> None:
    urdf, records, link, floor, rate = records_of(folder, logged, robot)
    plain = PlainFit(["--urdf", str(urdf)])
    train, validate, test = records["train"], records["validate"], records["test"]
    n = train.q.shape[1]
    print(f"\n== {'sagged (the encoders on the motors)' if logged else 'rigid (the links logged)'}")
    print(f"noise floor {floor.round(4).tolist()}")
    cutoff, theta = plain.fit(train, validate, rate_hz=rate)
    fit = CompliantPlainFit(plain, cutoff)
    rigid = fit.residual(test, np.zeros(n), theta)
    reference = np.mean(rigid**2, axis=0)
    print(f"plain fit (cut-off {cutoff} Hz): test {reference.round(4).tolist()} total {reference.sum():.4f}")
    if logged:
        at_links, at_links_theta = plain.fit(link["train"], link["validate"], rate_hz=rate)
        on_links = CompliantPlainFit(plain, at_links).residual(link["test"], np.zeros(n), at_links_theta)
        mse = np.mean(on_links**2, axis=0)
        print(f"plain fit on the links' angles (cut-off {at_links} Hz): test {mse.round(4).tolist()} total "
              f"{mse.sum():.4f}, {(mse / reference).round(3).tolist()} of the logged angles' ({mse.sum() / reference.sum():.3f})")
        truth = np.array([np.max(np.abs(train.tau[:, j])) / np.radians(0.5) for j in range(n)])
        print(f"true stiffness of joints 2, 3: {truth[1:3].round(0).tolist()} N m/rad")
    held, adopted = fit.residual(validate, np.zeros(n), theta), []
    while True:  # forward selection: each step tries every joint not yet taken together with those taken
        steps = []
        for joint in (joint for joint in range(n) if joint not in adopted):
            c, theta_joint = fit.gauss_newton(train, (*adopted, joint))
            difference, error = paired(fit.residual(validate, c, theta_joint), held)
            positive = bool(np.all(c[[*adopted, joint]] > 0))
            with np.errstate(divide="ignore"):  # a zero column's compliance stays 0: k infinite
                stiffness = np.round(1.0 / c[[*adopted, joint]], 0).tolist()
            print(f"  joints {[j + 1 for j in (*adopted, joint)]}: k {stiffness} "
                  f"N m/rad, validation {difference:+.4f} (se {error:.4f})")
            if positive and difference < -TIED_SE * error:
                steps.append((difference, joint, c, theta_joint))
        if not steps:
            break
        difference, joint, c, theta_joint = min(steps, key=lambda step: step[0])
        adopted.append(joint)
        held = fit.residual(validate, c, theta_joint)
        print(f"  adopted joint {joint + 1}")
    if adopted:
        c, theta_adopted = fit.gauss_newton(train, tuple(adopted))
        mse = np.mean(fit.residual(test, c, theta_adopted) ** 2, axis=0)
        print(f"forward selection: joints {[joint + 1 for joint in adopted]}, k {(1.0 / c[adopted]).round(0).tolist()}; "
              f"test {mse.round(4).tolist()} total {mse.sum():.4f}, {(mse / reference).round(3).tolist()} of the "
              f"plain fit ({mse.sum() / reference.sum():.3f})")
    else:
        print("forward selection: nothing adopted")
    rigid_held = fit.residual(validate, np.zeros(n), theta)
    kept = [joint for joint in range(n) if joint not in still_columns(fit, train, theta)]
    while kept:  # backward elimination: every law together, the non-positive ones and then those the
        c, theta_kept = fit.gauss_newton(train, tuple(kept))  # validation does not miss dropped one at a time
        if np.any(c[kept] <= 0):
            kept = [joint for joint in kept if c[joint] > 0]
            continue
        residual = fit.residual(validate, c, theta_kept)
        losses = []
        for joint in kept:
            fewer = [other for other in kept if other != joint]
            c_fewer, theta_fewer = fit.gauss_newton(train, tuple(fewer)) if fewer else (np.zeros(n), theta)
            difference, error = paired(fit.residual(validate, c_fewer, theta_fewer), residual)
            losses.append((difference, joint, error))
        difference, joint, error = min(losses)
        if difference > TIED_SE * error:
            break
        print(f"  backward: joint {joint + 1} dropped (validation {difference:+.4f}, se {error:.4f})")
        kept.remove(joint)
    def against_none(label: str, joints: list[int], c, theta_law) -> bool:
        """Print the law on ``joints`` against none on validation, and its test error; whether it is adopted."""
        difference, error = paired(fit.residual(validate, c, theta_law), rigid_held)
        mse = np.mean(fit.residual(test, c, theta_law) ** 2, axis=0)
        taken = difference < -TIED_SE * error
        print(f"{label}: joints {[joint + 1 for joint in joints]}, k {(1.0 / c[joints]).round(0).tolist()}, "
              f"validation {difference:+.4f} (se {error:.4f}) against none: {'adopted' if taken else 'not adopted'}; "
              f"test {mse.round(4).tolist()} total {mse.sum():.4f}, {(mse / reference).round(3).tolist()} of the "
              f"plain fit ({mse.sum() / reference.sum():.3f})")
        return taken

    if kept:
        against_none("backward elimination", kept, *fit.gauss_newton(train, tuple(kept)))
    else:
        print("backward elimination: nothing kept")
    together = [joint for joint in range(n) if joint not in still_columns(fit, train, theta)]
    while together:  # one decision for the joints together: the non-positive laws dropped until none is left
        c, theta_together = fit.gauss_newton(train, tuple(together))
        if np.all(c[together] > 0):
            break
        together = [joint for joint in together if c[joint] > 0]
    taken = bool(together) and against_none("the joints together", together, c, theta_together)
    pruned = False
    while taken and len(together) > 1:  # a member whose removal does not raise the validation error dropped
        residual = fit.residual(validate, c, theta_together)
        removals = []
        for joint in together:
            fewer = [other for other in together if other != joint]
            c_fewer, theta_fewer = fit.gauss_newton(train, tuple(fewer))
            difference = paired(fit.residual(validate, c_fewer, theta_fewer), residual)[0]
            removals.append((difference, joint, c_fewer, theta_fewer))
        difference, joint, c_fewer, theta_fewer = min(removals, key=lambda removal: removal[0])
        if difference > 0 or np.any(c_fewer[[other for other in together if other != joint]] <= 0):
            break
        together.remove(joint)
        c, theta_together, pruned = c_fewer, theta_fewer, True
        print(f"  pruned joint {joint + 1} (validation {difference:+.4f} without it)")
    if pruned:
        against_none("the joints together, pruned", together, c, theta_together)
    c, theta_all = fit.gauss_newton(train, tuple(range(n)))
    mse = np.mean(fit.residual(test, c, theta_all) ** 2, axis=0)
    with np.errstate(divide="ignore"):
        print(f"every joint's law together (no selection): k {np.round(1.0 / c, 0).tolist()}; test total "
              f"{mse.sum():.4f} ({mse.sum() / reference.sum():.3f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=("ur10e", "puma"), default="ur10e")
    robot = parser.parse_args().robot
    with tempfile.TemporaryDirectory() as folder:
        for logged in (True, False):
            (Path(folder) / str(logged)).mkdir()
            traced(Path(folder) / str(logged), logged, robot)


if __name__ == "__main__":
    main()
