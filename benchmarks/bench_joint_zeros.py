"""The check of the encoders' zeros (``estimation.identification.joint_zeros``) on the real logs: does it stay quiet on
the logs zeroed as their URDF, and speak on the TX40's log in its own zeros (joints 2 and 3 a quarter turn off)?

For each robot of ``bench_real_robots.py`` (its files, its split) the verb runs with its defaults (``--friction``
left out, as a new user runs it), and the check's outcome is recorded as the verb computed it: the offsets named, the
held-out MSE ratios (total, mean of the channels'), whether it warned, its seconds, and the verb's seconds.
``tx40-logzeros`` is the TX40 with the motor positions as logged (``TX40_ZERO`` not applied). The verb
``identify-alone`` is ``oed identify`` without ``--validate`` (the check then holds out the training record's second
half). A name ending in ``-reversedJ`` (``kuka-reversed2``) is that robot's files with joint ``J``'s recorded direction
reversed (its position, rate and torque columns, joint or motor side, negated: the URDF's axis reversed). The check's
seconds are those of the verb's own call; "scan" is the same call again in the same process, with and without the
scan of the joints' directions (``directions=False``), the median of three each.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_joint_zeros.py [--robots kuka,panda,tx40,tx40-logzeros,emps]
        [--verbs identify,diagnose,identify-alone]
    PYTHONPATH=. .venv/bin/python benchmarks/bench_joint_zeros.py --simulated
    PYTHONPATH=. .venv/bin/python benchmarks/bench_joint_zeros.py --simulated-directions
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_real_robots as real  # noqa: E402

import oed.workflows.asbuilt as asbuilt  # noqa: E402
from estimation.identification.joint_zeros import check_joint_zeros  # noqa: E402
from oed.cli import main  # noqa: E402


def case_of(name: str, folder: Path) -> real.Case:
    if "-reversed" in name:
        name, joint = name.split("-reversed")
        case = case_of(name, folder)
        for path in case.files.values():
            frame = pd.read_csv(path)
            for prefix in ("q", "dq", "ddq", "tau", "qm", "dqm", "ddqm", "taum"):
                if f"{prefix}{joint}" in frame.columns:
                    frame[f"{prefix}{joint}"] = -frame[f"{prefix}{joint}"]
            frame.to_csv(path, index=False, float_format="%.10g")
        return case
    if name != "tx40-logzeros":
        return real.ROBOTS[name](folder)
    saved = real.TX40_ZERO.copy()
    real.TX40_ZERO[:] = 0.0
    try:
        return real.tx40(folder)
    finally:
        real.TX40_ZERO[:] = saved


def run(name: str, verb: str) -> str:
    checks = []

    calls = []

    def recorded(*args, **kwargs):
        started = time.perf_counter()
        check = check_joint_zeros(*args, **kwargs)
        checks.append((check, time.perf_counter() - started))
        calls.append((args, kwargs))
        return check

    asbuilt.check_joint_zeros = recorded
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        case = case_of(name, folder)
        errors = io.StringIO()
        started = time.perf_counter()
        validate = [] if verb == "identify-alone" else ["--validate", str(case.files["validate"])]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(errors):
            code = main([verb.removesuffix("-alone"), *case.robot, *case.options, "--data", str(case.files["train"]),
                         *validate, "--out", str(folder / "result.json")])
        seconds = time.perf_counter() - started
    asbuilt.check_joint_zeros = check_joint_zeros
    warned = any("offset from the robot description's zeros" in line or "look reversed against" in line
                 for line in errors.getvalue().splitlines())
    if not checks or checks[0][0] is None:
        return f"| {name} | {verb} | exit {code} | not run | | | {seconds:.1f} | |"
    check, check_seconds = checks[0]
    scans = {}
    for directions in (True, False, True, False, True, False):
        started = time.perf_counter()
        check_joint_zeros(*calls[0][0], **{**calls[0][1], "directions": directions})
        scans.setdefault(directions, []).append(time.perf_counter() - started)
    named = [f"j{index + 1} {np.rad2deg(check.offsets[index]):+.1f}° (held-out alone "
             f"{np.rad2deg(check.held_out_offsets[index]):+.1f}°)" for index in check.joints]
    signs = check.signs or (1,) * len(check.offsets)
    torque = check.torque_signs or (1,) * len(check.offsets)
    named += [f"j{index + 1} reversed ({'q' if signs[index] < 0 else ''}{'+' if signs[index] < 0 and torque[index] < 0 else ''}"
              f"{'tau' if torque[index] < 0 else ''})" for index in check.reversed_joints]
    return (f"| {name} | {verb} | {', '.join(named) or 'none'} | {check.total_ratio:.3f} · {check.mean_ratio:.3f} | "
            f"{'**yes**' if warned else 'no'} | {check_seconds:.2f} / {seconds:.1f} | "
            f"{np.median(scans[True]):.2f} / {np.median(scans[False]):.2f} |")


def simulated(seeds: int = 10) -> None:
    """How often the check warns on simulated PUMA records (3 and 6 joints; viscous and Coulomb friction, noise
    0.3 N·m, 1000 samples a record; another motion and parameters each seed) with correct zeros and with joint 2 a
    quarter turn off, held out on a validation record or on the training record's second half."""
    from dataclasses import replace

    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.simulation.synthetic import simulate, true_parameters
    from oed.fourier import random_fourier

    print("| robot | zeros | held out | warned | largest error of the named offset (rad) |")
    print("|---|---|---|---|---|")
    for joints in (6, 3):
        robot = load_robot("puma560", joints=joints)
        model = build_model(robot, "internal", "viscous,coulomb")
        noise = {f"tau{j}": 0.3 for j in range(1, joints + 1)}
        quarter = np.zeros(joints)
        quarter[1] = -np.pi / 2
        outcomes: dict[tuple[str, str], list[float | None]] = {}
        for seed in range(seeds):
            theta = true_parameters(model, seed=seed)
            train = simulate(model, theta, random_fourier(robot, 100 + seed), noise=noise, seed=200 + seed)
            validate = simulate(model, theta, random_fourier(robot, 300 + seed), noise=noise, seed=400 + seed)
            for zeros, offsets in (("correct", np.zeros(joints)), ("joint 2 a quarter turn off", quarter)):
                for held_out in ("validation record", "second half"):
                    check = check_joint_zeros(model, replace(train, q=train.q - offsets),
                                              replace(validate, q=validate.q - offsets)
                                              if held_out == "validation record" else None, warn=False)
                    warned = check is not None and check.marked
                    error = abs(check.offsets[1] - offsets[1]) if warned and offsets[1] else None
                    outcomes.setdefault((zeros, held_out), []).append(error if warned else np.nan)
        for (zeros, held_out), values in outcomes.items():
            warned = [value for value in values if not np.isnan(value)]
            largest = f"{max(warned):.3f}" if warned and zeros != "correct" else "–"
            print(f"| PUMA {joints} joints | {zeros} | {held_out} | {len(warned)} of {len(values)} | {largest} |")


def simulated_directions(seeds: int = 10, sizes: tuple[int, ...] = (6, 3)) -> None:
    """How often the check names a reversed joint on simulated PUMA records (3 and 6 joints, as :func:`simulated`):
    each joint in turn reversed (``q``, ``dq``, ``ddq`` and its torque: the URDF's axis reversed; or ``q``, ``dq``,
    ``ddq`` only; or the torque only), held out on a validation record or on the training record's second half;
    "right" counts the warnings that name that joint with that convention and nothing else."""
    from dataclasses import replace

    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.simulation.synthetic import simulate, true_parameters
    from oed.fourier import random_fourier

    print("| robot | reversed | held out | warned | right | held-out MSE ratio total (median of the warned) |")
    print("|---|---|---|---|---|---|")
    for joints in sizes:
        robot = load_robot("puma560", joints=joints)
        model = build_model(robot, "internal", "viscous,coulomb")
        noise = {f"tau{j}": 0.3 for j in range(1, joints + 1)}
        cases = [("none", None, 1, 1)] + [(f"joint {joint + 1}, {label}", joint, kinematic, torque)
                                          for joint in range(joints)
                                          for label, kinematic, torque in (("q and tau", -1, -1), ("q only", -1, 1),
                                                                           ("tau only", 1, -1))]
        outcomes: dict[tuple[str, str], list[tuple[bool, bool, float]]] = {}
        for seed in range(seeds):
            theta = true_parameters(model, seed=seed)
            train = simulate(model, theta, random_fourier(robot, 100 + seed), noise=noise, seed=200 + seed)
            validate = simulate(model, theta, random_fourier(robot, 300 + seed), noise=noise, seed=400 + seed)
            for label, joint, kinematic, torque in cases:
                signs, torques = np.ones(joints), np.ones(joints)
                if joint is not None:
                    signs[joint], torques[joint] = kinematic, torque

                def logged(record, signs=signs, torques=torques):
                    return replace(record, q=record.q * signs, dq=record.dq * signs, ddq=record.ddq * signs,
                                   tau=record.tau * torques)

                for held_out in ("validation record", "second half"):
                    check = check_joint_zeros(model, logged(train), logged(validate)
                                              if held_out == "validation record" else None, warn=False)
                    warned = check is not None and check.marked
                    right = warned and joint is not None and check.reversed_joints == (joint,) and \
                        check.signs[joint] == kinematic and check.torque_signs[joint] == torque and not check.joints
                    outcomes.setdefault((label, held_out), []).append((warned, right, check.total_ratio
                                                                        if warned else np.nan))
        for (label, held_out), values in outcomes.items():
            warned = sum(value[0] for value in values)
            ratios = [value[2] for value in values if value[0]]
            ratio = f"{np.median(ratios):.3f}" if ratios else "–"
            print(f"| PUMA {joints} joints | {label} | {held_out} | {warned} of {len(values)} | "
                  f"{sum(value[1] for value in values)} | {ratio} |", flush=True)


def main_benchmark() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="kuka,panda,tx40,tx40-logzeros,emps")
    parser.add_argument("--verbs", default="identify,diagnose")
    parser.add_argument("--simulated", action="store_true", help="the simulated PUMA records instead (10 seeds)")
    parser.add_argument("--simulated-directions", action="store_true",
                        help="the simulated PUMA records with a joint reversed instead (10 seeds)")
    parser.add_argument("--seeds", type=int, default=10, help="with --simulated-directions: seeds a robot")
    parser.add_argument("--joints", default="6,3", help="with --simulated-directions: the PUMAs' joint counts")
    args = parser.parse_args()
    if args.simulated:
        simulated()
        return
    if args.simulated_directions:
        simulated_directions(args.seeds, tuple(int(size) for size in args.joints.split(",")))
        return
    print("| log | verb | joints named | held-out MSE ratio total · mean | warned | check / verb s | check with / "
          "without the directions' scan s |")
    print("|---|---|---|---|---|---|---|")
    for verb in args.verbs.split(","):
        for name in args.robots.split(","):
            print(run(name, verb), flush=True)


if __name__ == "__main__":
    main_benchmark()
