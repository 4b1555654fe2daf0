"""Benchmark (issue 34, h-pandadiag): where the default ``oed diagnose`` gains or loses against ``oed identify`` on
a record no choice saw, effect by effect.

For one real robot of :mod:`benchmarks.bench_real_robots` (its three records):

1. ``oed diagnose`` (the library call, its defaults) on the training and validation records, the test record
   given so that the records are prepared alike; ``oed identify`` (``--friction viscous,coulomb,offset``, its
   defaults) on the same files, then ``oed predict`` on the validation record.
2. The diagnosed model rebuilt effect by effect in the order the search adopted them: the declared model, then
   each adopted effect added (the declared viscous terms, the last row with the joint refit's: the diagnosed model;
   shapes started at the diagnosis's), each nested
   model fitted as the diagnosis fits (channel-weighted least squares on the diagnosis's prepared records), its
   validation MSE per channel and its test MSE per joint over the plain least-squares fit's on the recorded samples
   the benchmark scores (:func:`benchmarks.bench_real_robots.compare`'s window and re-sent rows).
3. Rows beside them: the diagnosed model with the plain law completed (an offset on each joint without one), with
   the armature on every joint, and the plain class (viscous, Coulomb, offset) alone and with the armature.
4. The two verbs' answers on the validation record by the default answer's criterion (each channel's MSE over
   the smaller of the two, averaged over the channels): whether the diagnosis's answer wins on validation and
   loses on the test, or loses on both.

Run: ``PYTHONPATH=. python benchmarks/bench_diagnosis_trace.py [--robot panda]`` (about 5 minutes for the Panda).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import warnings
from pathlib import Path

import numpy as np

from benchmarks.bench_real_robots import FRICTION, ROBOTS, SETTLING, PlainFit, resent, run_quiet
from dynamics.effects.linear import Armature, CoulombFriction, JointOffset, ViscousFriction
from dynamics.models import build_model
from estimation.diagnosis.candidates.trials import candidate_label
from estimation.identification.fit import identify
from oed.workflows.diagnose import diagnose


def ratios_line(label: str, validation: np.ndarray, test: np.ndarray, plain: np.ndarray) -> str:
    ratio = test / plain
    return (f"| {label} | " + " ".join(f"{v:.4g}" for v in validation) + " | " + " ".join(f"{v:.3f}" for v in ratio)
            + f" | {test.sum() / plain.sum():.3f} · {ratio.mean():.3f} · {ratio.max():.3f} (j{ratio.argmax() + 1}) |")


def trace(robot: str, folder: Path) -> list[str]:
    case = ROBOTS[robot](folder)
    options = dict(zip(case.robot[::2], case.robot[1::2]))
    source = {"urdf": options["--urdf"]} if "--urdf" in options else {"robot": options["--robot"]}
    if case.options:
        source["transmission"] = dict(zip(case.options[::2], case.options[1::2]))["--transmission"]
    plain_fit = PlainFit(case.robot)
    cutoff, theta = plain_fit.fit(case.records["train"], case.records["validate"])
    recorded = case.records["test"]
    predicted, kept = plain_fit.predict(recorded, cutoff, theta)
    scored = kept & ~resent(recorded)
    plain = np.mean((recorded.tau[scored] - predicted[scored]) ** 2, axis=0)
    trim = SETTLING / cutoff

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = diagnose(data=[case.files["train"]], validate=[case.files["validate"]], test=[case.files["test"]],
                       **source)
    records, diagnosis = run.records, run.diagnosis
    train, validation, test = (records.train.measurements, records.validation.measurements,
                               records.test.measurements)
    after = diagnosis.after.model
    shapes = {name: value for effect in diagnosis.effects for name, value in effect.shape.items()}
    viscous = [effect for effect in after.effects if isinstance(effect, ViscousFriction)]
    adopted = [effect for effect in after.effects if not isinstance(effect, ViscousFriction)]

    def fitted(effects: list) -> tuple[np.ndarray, np.ndarray]:
        model = build_model(after.robot, after.kind, tuple(effects))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            on_validation = identify(model, train, validation, shape_starts=shapes or None)
            on_test = identify(model, train, test, shape_starts=shapes or None).validation
        window = (on_test.t >= recorded.t[0] + trim) & (on_test.t <= recorded.t[-1] - trim)
        return (np.array(list(on_validation.validation.mse.values())),
                np.mean((on_test.measured[window] - on_test.predicted[window]) ** 2, axis=0))

    n = after.robot.n_joints
    lines = [f"**{case.name}**: the diagnosed model effect by effect (channel-weighted least squares on the "
             f"diagnosis's records); validation MSE per channel, test MSE per joint over the plain fit's "
             f"(cut-off {cutoff:g} Hz), total · mean · worst", "",
             "| model | validation MSE | test / plain | total · mean · worst |", "|---|---|---|---|"]
    lines.append(ratios_line("declared", *fitted(list(diagnosis.before.model.effects)), plain))
    declared = list(diagnosis.before.model.effects)
    for k, effect in enumerate(adopted, start=1):  # the search's models: the declared viscous terms, all of them
        joints = getattr(effect, "joints", ())  # a law on a joint combination names its joints in its label
        label = (f"+ {candidate_label(effect)}" + ("" if joints == () else " on " + ",".join(
            str(j + 1) for j in (joints or range(n))))
                 + ("" if k < len(adopted) else " (the joint refit's viscous terms: the diagnosed model)"))
        lines.append(ratios_line(label, *fitted((declared if k < len(adopted) else viscous) + adopted[:k]), plain))
    with_offset = {j for effect in after.effects if isinstance(effect, JointOffset) for j in (effect.joints or range(n))}
    completion = [JointOffset(joints=(j,)) for j in range(n) if j not in with_offset]
    with_armature = {j for effect in after.effects if isinstance(effect, Armature) for j in (effect.joints or range(n))}
    armature = [Armature(joints=(j,)) for j in range(n) if j not in with_armature]
    rows = {"diagnosed + the plain law's offsets": list(after.effects) + completion,
            "diagnosed + armature (on each joint without one)": list(after.effects) + armature,
            "plain class (viscous, Coulomb, offset)": [ViscousFriction(), CoulombFriction(), JointOffset()],
            "plain class + armature": [ViscousFriction(), CoulombFriction(), JointOffset(), Armature()]}
    for label, effects in rows.items():
        lines.append(ratios_line(label, *fitted(effects), plain))

    # the two verbs' answers on the validation record
    answer = folder / "identify.json"
    run_quiet(["identify", *case.robot, *case.options, "--data", str(case.files["train"]), "--validate",
               str(case.files["validate"]), "--friction", FRICTION, "--out", str(answer)])
    document = json.loads(answer.read_text())
    identified = np.array(list(document["validation"]["mse"].values()))
    chosen = run.to_dict()["model_selection"]
    answered = next(c for c in chosen["candidates"] if c["name"] == chosen["chosen"])
    diagnosed_validation = np.array(list(answered["validation_mse"].values()))
    smaller = np.minimum(identified, diagnosed_validation)
    lines += ["", f"answers on the validation record (each channel's MSE over the smaller of the two, averaged): "
                  f"diagnose ({chosen['chosen']}) {np.mean(diagnosed_validation / smaller):.4f}, identify "
                  f"({document['model_selection']['chosen']}) {np.mean(identified / smaller):.4f}; identify's torque "
                  f"gains: {'taken' if (document.get('torque_gains') or {}).get('taken') else 'not taken'}, its "
                  f"effects: {document['model_file'].get('effects')}"]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda", choices=sorted(ROBOTS))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        print("\n".join(trace(args.robot, Path(folder))), flush=True)


if __name__ == "__main__":
    main()
