"""A 6-joint PUMA 560 whose last motor turns with ``q5 + q6``, with motor-side friction (issue 18).

Simulates two 0.5 Hz Fourier experiments (2 000 samples each at 1 kHz, true dq/ddq, torque noise
0.2 N·m) on the PUMA with the motors' viscous and Coulomb friction (Corke's motor data) acting
through a transmission, then compares per channel the validation MSE of

* ``zero``: a zero torque; ``nominal``: the DH/inertial values with no friction;
* ``per-joint``: viscous + Coulomb + armature per joint (the data converted to joint space, no
  transmission declared: what a user gets without this issue);
* ``diagnosed``: ``oed diagnose`` from ``viscous,armature`` without the transmission;
* ``motor``: the transmission declared (``armature,motor_viscous,motor_coulomb``),

all with ``--min-speed 0.05`` (rows at rest dropped), and prints the motor Coulomb estimates
against the truth. ``--wrist puma`` uses the PUMA's own (weak) coupling instead of ``q5 + q6``.

    python benchmarks/asbuilt_wrist.py [--wrist q5+q6|puma] [--min-speed 0.05]

(from a checkout: ``PYTHONPATH=. python benchmarks/asbuilt_wrist.py``, or the installed package's
modules are imported.)

Research notes (issue 18, the ``q5 + q6`` wrist; validation MSE over the 0.04 N²m² floor). The
diagnosis left tau5 at 2.49x (0.0996) and tau6 at 1.10x, for two reasons measured apart:

1. Order of selection: a joint-5 ``coulomb:tanh`` was taken before ``viscous[q5+q6]``, with a wide
   smoothing (0.28 rad/s) that absorbed part of that still missing viscous term. After
   ``viscous[q5+q6]`` was added, the joint refit ran the smoothing to its lower bound (the sign law;
   the rows below 0.05 rad/s are dropped) and was refused as undetermined, so the stale shape was
   kept. The same effects with the plain law give 1.10x. Fix: :mod:`estimation.diagnosis.limit_laws` (a
   ``coulomb:tanh`` whose refit runs to the bound is replaced by ``coulomb``): tau5 1.10x.
2. The candidate's law: ``coulomb[q5+q6]`` is a sign law, the motor's is smooth on the joint side
   below ``1/G6 = 0.013`` rad/s, and 5 % of the kept rows lie there (q5 and q6 turning against each
   other). ``fc[q5+q6]`` came out 0.493 ± 0.013 for 0.554 (4.6 standard deviations low). A smoothed
   candidate ``coulomb:tanh[q5+q6]`` tried alone was worse: taken first with ``vc = 1.1`` rad/s it
   mimicked the missing viscous term, ``viscous[q5+q6]`` was then refused, tau5/tau6 2.29x/2.20x.
   Tried as one candidate with ``viscous[q5+q6]`` (a motor's friction is both;
   :func:`estimation.diagnosis.candidates.coupling.combination_groups`): fc 0.551 ± 0.009, vc 0.0126 ± 0.0013
   (0.0130), fv 0.217 ± 0.005 (0.216), tau5/tau6 1.00x/1.01x.
"""

from __future__ import annotations

import argparse

import numpy as np

from dynamics.effects.specs import build_effects
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.sensors import NoiseModel
from dynamics.simulation.joint_effects import PUMA560_ROTOR_INERTIA, SimulatedArmature
from dynamics.simulation.motor_effects import MotorFriction
from dynamics.simulation.simulator import Simulator
from dynamics.transmission import Transmission, puma560_transmission
from estimation.diagnosis.search import diagnose
from estimation.identification.fit import identify
from estimation.data.rest import coulomb_combinations, drop_rest
from estimation.identification.trivial_predictors import trivial_mse
from oed.fourier import random_fourier


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--wrist", choices=("q5+q6", "puma"), default="q5+q6")
    parser.add_argument("--min-speed", type=float, default=0.05)
    args = parser.parse_args()
    robot = load_robot("puma560")
    transmission = puma560_transmission()
    if args.wrist == "q5+q6":
        matrix = np.diag(transmission.ratios)
        matrix[5, 4] = matrix[5, 5]
        transmission = Transmission(matrix)
    base = MotorFriction.default(robot)
    friction = MotorFriction(tuple(map(tuple, transmission.matrix)), base.viscous, base.coulomb, (1.0,))
    rotor = np.diag(transmission.matrix.T @ np.diag(PUMA560_ROTOR_INERTIA) @ transmission.matrix)
    simulator = Simulator(robot, (friction, SimulatedArmature(tuple(rotor))), noise=NoiseModel())
    train, validate = (simulator.run(random_fourier(robot, seed=seed, frequency_hz=0.5), periods=1, warmup_periods=1,
                                     with_derivatives=True, seed=seed).measurements for seed in (3, 4))

    def fit(spec, declared=None):
        effects = build_effects(spec, robot, declared)
        combinations = coulomb_combinations(effects)
        model = build_model(robot, "internal", effects)
        kept = [drop_rest(data, args.min_speed, combinations=combinations).measurements for data in (train, validate)]
        return identify(model, *kept), kept

    rows = {}
    joint, kept = fit("viscous,coulomb,armature")
    rows.update(trivial_mse(joint.model, kept[1]))
    rows["per-joint"] = joint.validation.mse
    declared = build_model(robot, "internal", "viscous,armature")
    diagnosis = diagnose(declared, *kept)
    rows["diagnosed"] = diagnosis.after.validation.mse
    motor, _ = fit("armature,motor_viscous,motor_coulomb", transmission)
    rows["motor"] = motor.validation.mse
    print(f"wrist {args.wrist}, --min-speed {args.min_speed}: validation samples kept {kept[1].n_samples} of "
          f"{validate.n_samples}; noise floor {0.2 ** 2:.3g} N²m²")
    print("validation MSE  " + "".join(f"{channel:>10s}" for channel in declared.channels))
    for label, mse in rows.items():
        print(f"  {label.removesuffix('_mse'):<13s} " + "".join(f"{mse[channel]:10.4g}" for channel in declared.channels))
    print("diagnosis added: " + ", ".join(effect.spec + ("" if "[" in effect.spec else f"@{effect.channels[0][3:]}")
                                          for effect in diagnosis.effects))
    for effect in diagnosis.effects:
        if "[" in effect.spec:
            shape = "".join(f", {name} = {value:.4g} ± {effect.shape_std[name]:.2g}" for name, value in effect.shape.items())
            print(f"  {effect.parameters[0]} = {effect.values[0]:.4g} ± {effect.std[0]:.2g}{shape}")
    truth = friction.parameters(robot)
    print("motor Coulomb (N·m): estimate ± std (truth, deviation in std)")
    for record in motor.estimate.records():
        if record["expression"].startswith("fcm"):
            value = truth[record["expression"]]
            print(f"  {record['name']}: {record['value']:.5g} ± {record['std']:.2g} ({value:.5g}, "
                  f"{(record['value'] - value) / record['std']:+.1f})")


if __name__ == "__main__":
    main()
