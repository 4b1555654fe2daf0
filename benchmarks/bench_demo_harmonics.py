"""The demo's experiments fitted with the true model (Coulomb smoothing known): validation MSE over
the noise floor and the largest error in standard deviations, for 15 and 300 harmonics of the
Fourier differentiation, classical and HAC standard deviations.

Measured (issue 13, floor workstream): 15 harmonics: MSE/floor 301 / 12 / 19, fc3 15.1 classical
standard deviations off (1.7 HAC); 300 harmonics: 1.63 / 1.13 / 0.93, largest error 2.4 (2.0 HAC).

Run: ``PYTHONPATH=. python benchmarks/bench_demo_harmonics.py`` (about a minute).
"""
import warnings

from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.simulator import NoiseModel, Simulator
from estimation.identification.fit import identify
from estimation.uncertainty.noise_floor import noise_floor, prepared_floor
from estimation.preprocessing.differentiation import FourierDifferentiation, fill_derivatives
from oed.excitation import design_excitation

warnings.simplefilter("ignore")
robot = load_robot("puma560", joints=3)
sim = Simulator(robot, "viscous,coulomb,offset", noise=NoiseModel())
ctrl = sim.default_controller(bandwidth_hz=20.0)
raw = {}
for i, (label, seed) in enumerate((("train", 0), ("validate", 7))):
    traj = design_excitation(robot, model="internal", starts=2, seed=seed).trajectory
    raw[label] = (traj, sim.run(traj, ctrl, periods=3, warmup_periods=1, seed=i + 1).measurements)
model = build_model(robot, "internal", ("viscous", CoulombFriction(smoothing=0.05), "offset"))
truth = dict(zip(model.base.names, model.base.to_base(sim.true_theta(model))))
floor = noise_floor(raw["validate"][1], model.channels)
for H in (15, 300):
    data = {k: fill_derivatives(m, FourierDifferentiation(t.frequency_hz, harmonics=H), held_torques=True) for k, (t, m) in raw.items()}
    for cov in ("classical", "hac"):
        r = identify(model, data["train"], data["validate"], covariance=cov)
        f = prepared_floor(floor, data["validate"]).mse()
        z = {n: (v - truth[n]) / s for n, v, s in zip(r.estimate.names, r.estimate.values, r.estimate.std)}
        worst = max(z, key=lambda n: abs(z[n]))
        print(f"H={H} {cov}: val MSE/floor", {c: round(v / f[c], 2) for c, v in r.validation.mse.items()},
              f"max |error|/std {worst} {z[worst]:.1f}; fc:", {n: (round(r.estimate.values[i], 2), round(r.estimate.std[i], 3)) for i, n in enumerate(r.estimate.names) if n.startswith("fc")})
print("floor (raw, periods)", floor.mse(), "truth fc", {n: round(v, 2) for n, v in truth.items() if n.startswith("fc")})
