"""Benchmark (issue 34, h-reach): what the candidates of ``oed identify`` predict beyond the training's reach.

The validation record cannot see the difference between candidates along motions that neither it nor the training
record excites (h-shortval2: the Panda's records cut short). This measures, for each candidate the result file holds
(``--alternative ols|wls|consistent``), what a **reference motion that is not a record** says of it: the training
record's motion replayed at positions shifted over the description's joint limits (its velocities and accelerations
as they are; per copy, each joint's shift drawn by a Latin hypercube over the room its limits leave beside the
training range; ``COPIES`` copies, seeded). Per candidate:

* its validation score (the selection's criterion: the mean over channels of its validation MSE over the smallest
  any candidate reaches on that channel);
* its **extra band variance on the reference motion**: the mean over the reference samples of the 95 % band's
  variance (``y_bᵀ Σ_θ y_b + σ_c²``) less the same on the validation record, per channel over the same smallest
  validation MSE, averaged over the channels (the criterion's units): an estimate of the MSE a motion spanning the
  joint ranges adds beyond what the validation measured, if the candidate is unbiased;
* its **reach score**: the validation score plus that term;
* its disagreement with the chosen candidate on the reference motion and on the validation record (mean over
  channels of the mean squared difference of the predictions over the smallest validation MSE): how much more the
  candidates differ where no record went;
* its test MSE per joint over the plain least-squares fit's (the test record no choice saw), as
  ``bench_short_records.py`` scores it.

Run: ``python benchmarks/bench_reach.py [--robot panda] [--degradation short|"100 Hz"|none] [--verb identify|diagnose]``;
``python benchmarks/bench_reach.py --records FOLDER [--friction viscous,coulomb,offset]``: two answers of
``oed diagnose`` on one joint's records (the one-sided pendulum's: run its case of
``tests/test_unseen_robot_benches.py`` with ``--basetemp DIR``, the records are in its folder under ``DIR``);
``python benchmarks/bench_reach.py --results FOLDER...``: the candidates of the result files a lab's case left in its
folder (``default.json``, ``diagnose.json``).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.bench_real_degraded import DEGRADATIONS, at_recorded, record_of, resent, run_logged, run_verb
from benchmarks.bench_real_robots import ROBOTS, PlainFit, tx40_transmission
from benchmarks.bench_short_records import Z95, case_with_plain_fit
from dynamics.robots import load_robot

#: copies of the training motion in the reference motion
COPIES = 6


def shifts(lower: np.ndarray, upper: np.ndarray, q: np.ndarray, copies: int, seed: int = 0) -> np.ndarray:
    """``(copies, n)``: each copy's shift of the training positions ``q`` so that the copies spread over the
    limits (a Latin hypercube over the room each joint's limits leave beside its training range; zero where the
    limits are infinite or leave no room)."""
    generator = np.random.default_rng(seed)
    low, high = q.min(axis=0), q.max(axis=0)
    least, most = np.where(np.isfinite(lower), lower - low, 0.0), np.where(np.isfinite(upper), upper - high, 0.0)
    none = most < least  # a training range wider than its limits: not shifted
    least, most = np.where(none, 0.0, least), np.where(none, 0.0, most)
    result = np.zeros((copies, q.shape[1]))
    for joint in range(q.shape[1]):
        fractions = (generator.permutation(copies) + 0.5) / copies
        result[:, joint] = least[joint] + fractions * (most[joint] - least[joint])
    return result


def reference_files(case, robot_arguments: list[str], folder: Path) -> tuple[list[Path], np.ndarray]:
    """The reference motion's files (the training file, its positions shifted) and the training range's share of
    each joint's limits."""
    robot = load_robot(urdf=robot_arguments[1]) if robot_arguments[0] == "--urdf" else load_robot(robot_arguments[1])
    frame = pd.read_csv(case.files["train"])
    q = case.records["train"].q
    moved = shifts(robot.lower, robot.upper, q, COPIES)
    span = np.ptp(q, axis=0) / np.where(np.isfinite(robot.upper - robot.lower), robot.upper - robot.lower, np.inf)
    files = []
    for copy, shift in enumerate(moved):
        shifted = frame.copy()
        if "qm1" in frame.columns:
            motor = tx40_transmission() @ shift
            for joint in range(len(shift)):
                shifted[f"qm{joint + 1}"] = frame[f"qm{joint + 1}"] + motor[joint]
        else:
            for joint in range(len(shift)):
                shifted[f"q{joint + 1}"] = frame[f"q{joint + 1}"] + shift[joint]
        path = folder / f"reference_{copy}.csv"
        shifted.to_csv(path, index=False, float_format="%.10g")
        files.append(path)
    return files, span


def predicted(result: Path, name: str, data: Path, out: Path) -> pd.DataFrame:
    code, _, message = run_logged(["predict", "--model", str(result), "--alternative", name,
                                   "--data", str(data), "--out", str(out)])
    if code != 0:
        raise RuntimeError(f"oed predict --alternative {name} on {data.name}: {message}")
    return pd.read_csv(out)


def channel_band(table: pd.DataFrame, channels: list[str]) -> np.ndarray:
    return np.array([np.mean(((table[f"{c}_hi"] - table[f"{c}_lo"]) / (2 * Z95)) ** 2) for c in channels])


def reach_lines(robot: str, degradation: str, folder: Path, verb: str = "identify") -> list[str]:
    case, validation, predicted_plain, kept = case_with_plain_fit(robot, degradation, folder)
    test = case.records["test"]
    run = run_verb(case, validation, verb, folder)
    if run["exit"] != 0:
        return [f"{verb} exits {run['exit']}: {run['message']}"]
    result = folder / f"{verb}.json"
    document = json.loads(result.read_text())
    selection = document.get("model_selection") or {}
    references, span = reference_files(case, case.robot, folder)
    names = [c["name"] for c in selection.get("candidates", []) if c.get("available")]
    validate, reference, ratios = {}, {}, {}
    for name in names:
        validate[name] = predicted(result, name, case.files["validate"], folder / f"{name}_validate.csv")
        reference[name] = [predicted(result, name, path, folder / f"{name}_{path.stem}.csv") for path in references]
        table = predicted(result, name, case.files["test"], folder / f"{name}_test.csv")
        channels = [c for c in table.columns if c.startswith("tau") and c[3:].isdigit()]
        rows, values = at_recorded(test.t, table["t"].to_numpy(), table[channels].to_numpy())
        use = kept[rows] & ~resent(test)[rows]
        rows, values = rows[use], values[use]
        mse = np.mean((test.tau[rows] - values) ** 2, axis=0)
        ratios[name] = mse / np.mean((test.tau[rows] - predicted_plain[rows]) ** 2, axis=0)
    channels = [c for c in validate[names[0]].columns if c.startswith("tau") and c[3:].isdigit()]
    recorded = case.records["validate"]
    measured = {}
    for name in names:
        rows, values = at_recorded(recorded.t, validate[name]["t"].to_numpy(), validate[name][channels].to_numpy())
        measured[name] = np.mean((recorded.tau[rows] - values) ** 2, axis=0)
    smallest = np.min([measured[name] for name in names], axis=0)
    chosen = selection.get("chosen")
    lines = [f"{robot}, {degradation}: {verb} chose {chosen} ({selection.get('reason')}); training range over "
             f"the limits per joint: {', '.join(f'{s:.2f}' for s in span)}", "",
             "| candidate | validation score | extra band variance on the reference | reach score | disagreement "
             f"with {chosen}: validation · reference | test / plain: total · mean · worst |",
             "|---|---|---|---|---|---|"]
    for name in names:
        score = float(np.mean(measured[name] / smallest))
        extra = np.mean([channel_band(table, channels) for table in reference[name]], axis=0) - channel_band(
            validate[name], channels)
        extra = float(np.mean(extra / smallest))
        apart_validate = float(np.mean(np.mean((validate[name][channels].to_numpy()
                                                 - validate[chosen][channels].to_numpy()) ** 2, axis=0) / smallest))
        apart_reference = float(np.mean(np.mean([np.mean((mine[channels].to_numpy() - theirs[channels].to_numpy())
                                                          ** 2, axis=0) for mine, theirs in
                                                 zip(reference[name], reference[chosen])], axis=0) / smallest))
        ratio = ratios[name]
        lines.append(f"| {name} | {score:.3f} | {extra:+.3f} | {score + extra:.3f} | {apart_validate:.3f} · "
                     f"{apart_reference:.3f} | {ratio.mean():.3f} (mean) · {ratio.max():.3f} (j{ratio.argmax() + 1})"
                     f"; {', '.join(f'{r:.2f}' for r in ratio)} |")
    return lines


def answers_lines(records_folder: Path, friction: str, folder: Path) -> list[str]:
    """Two ``oed diagnose`` answers on a folder's records (``robot.urdf``, ``train.csv``, ``validate.csv``,
    ``test.csv``, one joint): the default and ``--friction friction`` declared, each scored as :func:`reach_lines`
    scores the candidates. The one-sided pendulum of ``tests/test_unseen_robot_benches.py`` (trained and validated
    on its lowest 35 % of swing): its default keeps no offset (the completed model tied within
    ``COMPLETION_TOLERANCE``), ``viscous,coulomb,offset`` declares the law the tie left out."""
    urdf = records_folder / "robot.urdf"
    files = {role: records_folder / f"{role}.csv" for role in ("train", "validate", "test")}
    records = {role: record_of(pd.read_csv(path)) for role, path in files.items()}
    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, theta = plain.fit(records["train"], records["validate"])
    test = records["test"]
    predicted_plain, kept = plain.predict(test, cutoff, theta)
    robot = load_robot(urdf=urdf)
    frame = pd.read_csv(files["train"])
    q = records["train"].q
    moved = shifts(robot.lower, robot.upper, q, COPIES)
    references = []
    for copy, shift in enumerate(moved):
        shifted = frame.copy()
        shifted["q1"] = frame["q1"] + shift[0]
        references.append(folder / f"reference_{copy}.csv")
        shifted.to_csv(references[-1], index=False, float_format="%.10g")
    answers = {}
    for label, more in (("default", []), ("declared", ["--friction", friction])):
        result = folder / f"{label.replace(' ', '_')}.json"
        code, _, message = run_logged(["diagnose", "--urdf", str(urdf), "--data", str(files["train"]), "--validate",
                                       str(files["validate"]), *more, "--out", str(result)])
        if code != 0:
            return [f"diagnose {label} exits {code}: {message}"]
        answers[label] = result
    lines = [f"{records_folder.name}: training over {q.min():.2f}..{q.max():.2f} rad, limits {robot.lower[0]:.2f}.."
             f"{robot.upper[0]:.2f} rad, reference shifts {', '.join(f'{s:+.2f}' for s in moved[:, 0])} rad", "",
             "| answer | validation score | extra band variance on the reference | reach score | disagreement with "
             "the default: validation · reference | test / plain |", "|---|---|---|---|---|---|"]
    validate, band, ratio, tables = {}, {}, {}, {}
    for label, result in answers.items():
        table = predicted_on(result, files["validate"], folder / f"{label}_validate.csv")
        rows, values = at_recorded(records["validate"].t, table["t"].to_numpy(), table[["tau1"]].to_numpy())
        validate[label] = np.mean((records["validate"].tau[rows] - values) ** 2, axis=0)
        tables[label] = [table] + [predicted_on(result, path, folder / f"{label}_{path.stem}.csv")
                                   for path in references]
        band[label] = np.mean([channel_band(shifted, ["tau1"]) for shifted in tables[label][1:]], axis=0) \
            - channel_band(table, ["tau1"])
        table = predicted_on(result, files["test"], folder / f"{label}_test.csv")
        rows, values = at_recorded(test.t, table["t"].to_numpy(), table[["tau1"]].to_numpy())
        rows, values = rows[kept[rows]], values[kept[rows]]
        ratio[label] = np.mean((test.tau[rows] - values) ** 2) / np.mean((test.tau[rows] - predicted_plain[rows]) ** 2)
    smallest = np.min(list(validate.values()), axis=0)
    for label in answers:
        score, extra = float(np.mean(validate[label] / smallest)), float(np.mean(band[label] / smallest))
        apart = [float(np.mean((mine["tau1"].to_numpy() - theirs["tau1"].to_numpy()) ** 2) / smallest[0])
                 for mine, theirs in zip(tables[label], tables["default"])]
        lines.append(f"| {label} | {score:.3f} | {extra:+.3f} | {score + extra:.3f} | {apart[0]:.3f} · "
                     f"{np.mean(apart[1:]):.3f} | {ratio[label]:.3f} |")
    return lines


def result_folder_lines(folder: Path) -> list[str]:
    """A folder that holds a lab's records and its verbs' result files (``robot.urdf``, ``train.csv``,
    ``validate.csv``, ``test.csv``, ``default.json`` from ``oed identify``, ``diagnose.json``; what
    ``tests/test_unseen_robot_benches.py`` leaves in each case's folder): per verb, each candidate's disagreement with
    the chosen one on the validation record and on the reference motion, and its test MSE over the best candidate's
    (no plain fit here), both in the criterion's units."""
    robot = load_robot(urdf=folder / "robot.urdf")
    frame = pd.read_csv(folder / "train.csv")
    columns = [f"q{joint + 1}" for joint in range(robot.n_joints)]
    q = frame[columns].to_numpy(float)
    references = []
    for copy, shift in enumerate(shifts(robot.lower, robot.upper, q, COPIES)):
        shifted = frame.copy()
        shifted[columns] = q + shift
        references.append(folder / f"reference_{copy}.csv")
        shifted.to_csv(references[-1], index=False, float_format="%.10g")
    records = {role: pd.read_csv(folder / f"{role}.csv") for role in ("validate", "test")}
    lines = []
    for verb, name in (("identify", "default.json"), ("diagnose", "diagnose.json")):
        result = folder / name
        if not result.exists():
            continue
        selection = json.loads(result.read_text()).get("model_selection") or {}
        names, chosen = [c["name"] for c in selection.get("candidates", []) if c.get("available")], selection.get("chosen")
        if len(names) < 2 or chosen not in names:
            continue
        tables = {candidate: {role: predicted(result, candidate, folder / f"{role}.csv",
                                              folder / f"{verb}_{candidate}_{role}.csv") for role in records}
                  for candidate in names}
        reference = {candidate: [predicted(result, candidate, path, folder / f"{verb}_{candidate}_{path.stem}.csv")
                                 for path in references] for candidate in names}
        channels = [c for c in tables[chosen]["validate"].columns if c.startswith("tau") and c[3:].isdigit()]
        errors = {role: {} for role in records}
        for candidate in names:
            for role, recorded in records.items():
                rows, values = at_recorded(recorded["t"].to_numpy(), tables[candidate][role]["t"].to_numpy(),
                                           tables[candidate][role][channels].to_numpy())
                errors[role][candidate] = np.mean((recorded[channels].to_numpy()[rows] - values) ** 2, axis=0)
        smallest = {role: np.min(list(errors[role].values()), axis=0) for role in records}
        parts = []
        for candidate in (c for c in names if c != chosen):
            apart_validate = float(np.mean(np.mean((tables[candidate]["validate"][channels].to_numpy() - tables[
                chosen]["validate"][channels].to_numpy()) ** 2, axis=0) / smallest["validate"]))
            apart_reference = float(np.mean(np.mean([np.mean((mine[channels].to_numpy() - theirs[channels].to_numpy())
                                                             ** 2, axis=0) for mine, theirs in
                                                     zip(reference[candidate], reference[chosen])], axis=0)
                                            / smallest["validate"]))
            parts.append(f"{candidate} {apart_validate:.3f} -> {apart_reference:.3f} ("
                         f"{apart_reference / apart_validate if apart_validate > 0 else float('inf'):.1f}x), test "
                         f"{np.mean(errors['test'][candidate] / smallest['test']):.3f}")
        lines.append(f"{robot.name}, {folder.name}: {verb} chose {chosen} (test "
                     f"{np.mean(errors['test'][chosen] / smallest['test']):.3f}); {'; '.join(parts)}")
    return lines


def predicted_on(result: Path, data: Path, out: Path) -> pd.DataFrame:
    code, _, message = run_logged(["predict", "--model", str(result), "--data", str(data), "--out", str(out)])
    if code != 0:
        raise RuntimeError(f"oed predict {result.name} on {data.name}: {message}")
    return pd.read_csv(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda", choices=sorted(ROBOTS))
    parser.add_argument("--degradation", default="short", choices=[*DEGRADATIONS, "none"])
    parser.add_argument("--verb", default="identify", choices=["identify", "diagnose"])
    parser.add_argument("--records", type=Path, help="a folder of one joint's records: two diagnose answers instead")
    parser.add_argument("--friction", default="viscous,coulomb,offset", help="the declared answer's laws (--records)")
    parser.add_argument("--results", type=Path, nargs="+", help="folders of records and result files instead")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        if args.results:
            print("\n".join(line for path in args.results for line in result_folder_lines(path)), flush=True)
            return
        if args.records is not None:
            print("\n".join(answers_lines(args.records, args.friction, Path(folder))), flush=True)
            return
        print("\n".join(reach_lines(args.robot, args.degradation, Path(folder), args.verb)), flush=True)


if __name__ == "__main__":
    main()
