"""Robots and logs the project has not seen, as a new user brings them (issue 34), beside the other
``tests/test_unseen_robot*`` files:

- a description whose joints are named with spaces, dots and accents (``Schulter 1``, ``arm.elbow``,
  ``poignet_é``), as a vendor writes it (meshes by ``package://``, ``<transmission>`` and ``<gazebo>`` elements), the
  log's columns named by those joints and written by a Windows tool (a byte-order mark, CRLF line ends, a trailing
  comma on every line);
- the torque column the controller's command: it leads the motion it makes by 5 ms (the drive's current loop) and
  carries a constant bias per joint;
- a light two-joint arm on a table (both axes vertical: no gravity load) whose links weigh 0.25 and 0.12 kg: the
  motors' rotor inertia (armature, not in the description) and their friction dominate the torque;
- Fourier training, then validation and test both point-to-point moves with long stops (2 s), another kind of
  motion than the training's on every record a choice or the judge reads;
- a logger restarted during the training record, appending to its file: the header written again, the last 0.2 s
  written again after it (its time stamps going back), a row of ``NaN`` at the restart;
- a microcontroller's log: the time a 32-bit microsecond counter (``time_us``) that wraps to zero during the
  training record, at 200 Hz;
- torque noise with heavy tails (Student's t, the drives' interference);
- lost frames a fieldbus logger writes as rows of zeros (at 4d50ebf 805x the plain fit; now dropouts);
- encoder read errors (one sample 0.2 rad off; at 93a9290 2.68x the plain fit, a strict xfail: now dropouts,
  :func:`estimation.data.log_cleaning.encoder_glitches`), and read errors lasting 2 to 5 samples (at 4252663 345x,
  joint 1 749x: now dropouts alike), and a torque sensor clipped past its range (at 93a9290
  50.9x, a strict xfail: now its clipped samples left out of the fit and the errors,
  :func:`estimation.data.log_cleaning.saturated_samples`); the readers' own tests in ``tests/test_sensor_faults.py``.

No data are copied; every record is simulated as :mod:`tests.test_unseen_robot_labs` does (the plain fit's model
class, :func:`tests.test_unseen_robots.truth`, each case's effect, white torque noise of 2 % of each channel's
spread). Each case runs the default ``oed identify`` (told the plain fit's model class) and ``oed diagnose`` (its own
defaults), then ``oed predict`` on the test record no choice saw, against the plain Pinocchio least-squares fit of
``benchmarks/bench_real_robots.py`` on the same recorded samples (the plain fit reads the records as simulated,
before the logger's defects): per joint within 1.3x, in total at most 1.0x, each figure allowed its noise floor's
sampling spread; ``oed predict`` on the validation record reproduces the validation error each verb reported
(relative 1e-6); no verb names an effect the truth does not hold."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.robots import load_robot
from dynamics.urdf_export import robot_urdf
from tests.test_unseen_robot_benches import Bench, judged, marks, written
from tests.test_unseen_robot_labs import Lab, puma
from tests.test_unseen_robots import Log

#: the joints' names in the vendor's description (a space, a dot, an accent)
NAMES = ("Schulter 1", "arm.elbow", "poignet_é")

LIGHT_ARM = """<?xml version="1.0"?>
<robot name="light_arm">
  <link name="table"/>
  <joint name="riser" type="fixed"><origin xyz="0 0 0.05"/><parent link="table"/><child link="base"/></joint>
  <link name="base"><inertial><origin xyz="0 0 -0.02"/><mass value="0.6"/><inertia ixx="0.0004" ixy="0" ixz="0" iyy="0.0004" iyz="0" izz="0.0003"/></inertial></link>
  <joint name="shoulder" type="revolute"><origin xyz="0 0 0.03"/><axis xyz="0 0 1"/><parent link="base"/><child link="upper"/>
    <limit lower="-2.6" upper="2.6" velocity="6.0" effort="2"/></joint>
  <link name="upper"><inertial><origin xyz="0.1 0 0.01"/><mass value="0.25"/><inertia ixx="0.00005" ixy="0" ixz="0" iyy="0.0009" iyz="0" izz="0.0009"/></inertial></link>
  <joint name="elbow" type="revolute"><origin xyz="0.2 0 0.02"/><axis xyz="0 0 1"/><parent link="upper"/><child link="fore"/>
    <limit lower="-2.4" upper="2.4" velocity="8.0" effort="1"/></joint>
  <link name="fore"><inertial><origin xyz="0.075 0.005 0"/><mass value="0.12"/><inertia ixx="0.00002" ixy="0" ixz="0" iyy="0.00025" iyz="0" izz="0.00025"/></inertial></link>
</robot>
"""


def light_arm():
    return load_robot(urdf=written(LIGHT_ARM))


def named_puma():
    """The PUMA's first three joints with :data:`NAMES` as their names (the links named after them)."""
    text = robot_urdf(load_robot("puma560", joints=3))
    for old, new in zip(("joint1", "joint2", "joint3"), NAMES):
        text = text.replace(f'"{old}"', f'"{new}"').replace(f'"{old}_link"', f'"{new}_link"')
    return load_robot(urdf=written(text))


def as_a_vendor_writes_it(urdf: Path) -> None:
    """The description with what a vendor's URDF holds beside the dynamics: a mesh by ``package://`` on every link
    (a file nobody has here), a ``<transmission>`` per joint and a ``<gazebo>`` plugin."""
    text = urdf.read_text(encoding="utf-8")
    if "<transmission" in text:
        return
    for link in re.findall(r'<link name="([^"]+)"', text):
        visual = (f'<link name="{link}">\n    <visual><geometry><mesh filename="package://vendor_description/meshes/'
                  f'{link}.dae" scale="0.001 0.001 0.001"/></geometry></visual>')
        text = text.replace(f'<link name="{link}">', visual, 1).replace(f'<link name="{link}" />', visual + "</link>", 1)
    extras = "".join(
        f'  <transmission name="{joint} trans"><type>transmission_interface/SimpleTransmission</type>'
        f'<joint name="{joint}"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint>'
        f'<actuator name="{joint} motor"><mechanicalReduction>100</mechanicalReduction></actuator></transmission>\n'
        for joint in NAMES)
    extras += '  <gazebo><plugin name="control" filename="libgazebo_ros_control.so"/></gazebo>\n'
    urdf.write_text(text.replace("</robot>", extras + "</robot>"), encoding="utf-8")


def windows_export(path: Path) -> None:
    """The record's columns named by the joints (``<joint>_position``, ``_velocity``, ``_effort``) as a Windows
    tool writes them: a byte-order mark, CRLF line ends, a trailing comma on every line; the description beside it
    as its vendor writes it (:func:`as_a_vendor_writes_it`)."""
    as_a_vendor_writes_it(path.parent / "robot.urdf")
    table = pd.read_csv(path)
    words = {"q": "position", "dq": "velocity", "tau": "effort"}
    renamed = {}
    for column in table.columns:
        found = re.fullmatch(r"(q|dq|tau)(\d+)", column)
        if found:
            renamed[column] = f"{NAMES[int(found.group(2)) - 1]}_{words[found.group(1)]}"
    text = table.rename(columns=renamed).to_csv(index=False, float_format="%.10g")
    lines = [line + "," for line in text.rstrip("\n").split("\n")]
    path.write_bytes(("\ufeff" + "\r\n".join(lines) + "\r\n").encode("utf-8"))


def commanded(rate_hz: float, lead_s: float = 0.005, bias: float = 0.1):
    """What a controller logs as its torque: the command, ``lead_s`` ahead of the motion it makes (the log's torque
    at ``t`` is the joint's at ``t + lead_s``, interpolated; held at the record's end), plus a constant bias of
    ``bias`` of each channel's spread (alternating signs)."""

    def sensed(tau: np.ndarray, spread: np.ndarray) -> np.ndarray:
        rows = np.arange(tau.shape[0], dtype=float)
        ahead = np.column_stack([np.interp(rows + lead_s * rate_hz, rows, column) for column in tau.T])
        return ahead + bias * spread * (-1.0) ** np.arange(tau.shape[1])

    return sensed


def restarted(path: Path, at: float = 0.55, again: int = 50) -> None:
    """The training record as a logger restarted in it writes it: at ``at`` of its rows a row of ``NaN`` (the
    sample lost at the restart, its time stamp kept), then the header again and the last ``again`` rows again
    (a buffer flushed twice: their time stamps going back)."""
    if path.stem != "train":
        return
    lines = path.read_text().rstrip("\n").split("\n")
    header, rows = lines[0], lines[1:]
    cut = int(at * len(rows))
    stamp = rows[cut].split(",")[0]
    lost = ",".join([stamp] + ["NaN"] * (len(header.split(",")) - 1))
    path.write_text("\n".join([header, *rows[:cut], lost, header, *rows[cut - again:]]) + "\n")


def microseconds(path: Path, start_s: float = 4294.967296 - 4.0) -> None:
    """The training record's time as a microcontroller's 32-bit microsecond counter (``time_us``, integers) that
    started ``start_s`` s before the record and wraps to zero 4 s into it; the other records' time in seconds."""
    if path.stem != "train":
        return
    table = pd.read_csv(path)
    counter = (np.round((table["t"].to_numpy() + start_s) * 1e6).astype(np.int64)) % 2**32
    table.insert(0, "time_us", counter)
    table.drop(columns="t").to_csv(path, index=False, float_format="%.10g")


def zero_rows(path: Path, count: int = 8) -> None:
    """The training record as a fieldbus logger writes lost frames: ``count`` rows (none adjacent, away from the
    ends) whose every data cell is ``0`` (the time stamp kept)."""
    if path.stem != "train":
        return
    table = pd.read_csv(path)
    rows = np.random.default_rng(7).choice(np.arange(10, len(table) - 10, 3), count, replace=False)
    table.loc[rows, [column for column in table.columns if column != "t"]] = 0.0
    table.to_csv(path, index=False, float_format="%.10g")


def encoder_glitches(path: Path, count: int = 6, jump: float = 0.2, runs: bool = False) -> None:
    """The training record with ``count`` encoder read errors: one sample of one joint's position off by ``jump``
    rad (the joints in turn, the sign alternating), the next sample right again; ``runs``: lasting 2, 3, 4, 5, 2, 3
    samples (other rows, further apart)."""
    if path.stem != "train":
        return
    table = pd.read_csv(path)
    generator, tail, spacing = (np.random.default_rng(9), 20, 13) if runs else (np.random.default_rng(8), 10, 7)
    rows = generator.choice(np.arange(10, len(table) - tail, spacing), count, replace=False)
    joints = [column for column in table.columns if re.fullmatch(r"q\d+", column)]
    for index, row in enumerate(rows):
        length = 2 + index % 4 if runs else 1
        table.loc[row:row + length - 1, joints[index % len(joints)]] += jump * (-1.0) ** index
    table.to_csv(path, index=False, float_format="%.10g")


def encoder_read_runs(path: Path) -> None:
    """The training record with 6 encoder read errors lasting several samples (:func:`encoder_glitches`)."""
    encoder_glitches(path, runs=True)


def clipped(path: Path, share: float = 0.8) -> None:
    """The training record with joint 2's torque sensor past its range: its readings clipped at ``share`` of the
    largest magnitude it logged."""
    if path.stem != "train":
        return
    table = pd.read_csv(path)
    limit = share * float(np.abs(table["tau2"]).max())
    table["tau2"] = np.clip(table["tau2"], -limit, limit)
    table.to_csv(path, index=False, float_format="%.10g")


def clipped_everywhere(path: Path, share: float = 0.8) -> None:
    """Every record (training, validation, test) with joint 2's torque sensor past its range, clipped at ``share``
    of the largest magnitude each logged: the errors per joint over each joint's valid samples (a per-channel
    mask, :mod:`estimation.data.channel_mask`); the test's errors taken against the torques before clipping."""
    table = pd.read_csv(path)
    limit = share * float(np.abs(table["tau2"]).max())
    table["tau2"] = np.clip(table["tau2"], -limit, limit)
    table.to_csv(path, index=False, float_format="%.10g")


def heavy_tailed(degrees: float = 3.0, share: float = 0.02):
    """A torque sensor's noise with heavy tails (electromagnetic interference from the drives): Student's t with
    ``degrees`` degrees of freedom, scaled to ``share`` of each channel's spread, added to the white noise."""

    def sensed(tau: np.ndarray, spread: np.ndarray) -> np.ndarray:
        generator = np.random.default_rng(int(1e3 * abs(tau[0, 0])) % 2**32)
        return tau + generator.standard_t(degrees, tau.shape) * share * spread

    return sensed


def logs(seconds: tuple[float, float, float] = (10.0, 4.0, 6.0), rate: float = 250.0, **more) -> tuple[Log, ...]:
    return tuple(Log(duration, rate, velocity=False, **more) for duration in seconds)


#: each case, the logger's rewrite of its files (or ``None``)
USERS = (
    (Bench(Lab("PUMA 3 joints named 'Schulter 1', 'arm.elbow', 'poignet_é' in a vendor's URDF (meshes, transmissions, "
               "gazebo), columns named by joint, written with a BOM, CRLF and a trailing comma, 8 s / 3 s / 5 s at "
               "250 Hz, logged dq", named_puma, *(Log(seconds, 250.0) for seconds in (8.0, 3.0, 5.0)), slow=True)),
     windows_export),
    (Bench(Lab("PUMA 6 joints, the torque column the controller's command: 5 ms ahead of the motion and a constant "
               "bias per joint, 10 s / 4 s / 6 s at 500 Hz, logged dq", puma(6),
               *(Log(seconds, 500.0) for seconds in (10.0, 4.0, 6.0)), sensed=commanded(500.0), slow=True),
           may_name=("coulomb", "viscous", "offset", "delay")),
     None),
    (Bench(Lab("a light 2-joint arm on a table (links 0.25 and 0.12 kg, axes vertical), the motors' armature (not in "
               "the URDF) and friction dominating, 10 s / 4 s / 6 s at 250 Hz, no dq, point-to-point test",
               light_arm, *logs(), test_motion="point-to-point", armature=(0.012, 0.005),
               friction_scale=(0.1, 0.08), slow=True),
           may_name=("coulomb", "viscous", "offset", "armature")),
     None),
    (Bench(Lab("PUMA 6 joints, Fourier training, validation and test point-to-point with 2 s stops, 12 s / 10 s / "
               "10 s at 250 Hz, no dq", puma(6), *logs((12.0, 10.0, 10.0)), test_motion="point-to-point",
               validate_motion="point-to-point", rest=2.0, slow=True)),
     None),
    (Bench(Lab("PUMA 3 joints, the logger restarted in the training record (a NaN row, the header again, 0.2 s "
               "written twice, the clock going back), 10 s / 4 s / 6 s at 250 Hz, no dq", puma(3), *logs(),
               slow=True)),
     restarted),
    (Bench(Lab("PUMA 3 joints logged by a microcontroller: time_us a 32-bit counter wrapping to zero in the training "
               "record, 10 s / 4 s / 6 s at 200 Hz, no dq", puma(3), *logs(rate=200.0), slow=True)),
     microseconds),
    (Bench(Lab("PUMA 6 joints, torque noise with heavy tails (Student's t, 3 degrees of freedom, beside the white "
               "noise), 10 s / 4 s / 6 s at 250 Hz, no dq", puma(6), *logs(), sensed=heavy_tailed(), slow=True)),
     None),
    (Bench(Lab("PUMA 3 joints, 8 lost frames written as rows of zeros in the training record, 10 s / 4 s / 6 s at "
               "250 Hz, no dq", puma(3), *logs(), slow=True)),
     zero_rows),
    (Bench(Lab("PUMA 3 joints, 6 encoder read errors (one sample 0.2 rad off) in the training record, 10 s / 4 s / "
               "6 s at 250 Hz, no dq", puma(3), *logs(), slow=True)),
     encoder_glitches),
    (Bench(Lab("PUMA 3 joints, 6 encoder read errors lasting 2 to 5 samples (0.2 rad off) in the training record, "
               "10 s / 4 s / 6 s at 250 Hz, no dq", puma(3), *logs(), slow=True)),
     encoder_read_runs),
    (Bench(Lab("PUMA 3 joints, joint 2's torque sensor clipped at 80 % of its peak in the training record, 10 s / "
               "4 s / 6 s at 250 Hz, no dq", puma(3), *logs(), slow=True)),
     clipped),
    (Bench(Lab("PUMA 3 joints, joint 2's torque sensor clipped at 80 % of its peak in every record (training, "
               "validation, test), 10 s / 4 s / 6 s at 250 Hz, no dq", puma(3), *logs(), slow=True)),
     clipped_everywhere),
)


@pytest.mark.parametrize("bench, rewritten", [pytest.param(bench, rewritten, id=bench.name, marks=marks(bench))
                                              for bench, rewritten in USERS])
def test_the_defaults_run_and_predict_a_new_users_log_as_well_as_a_plain_fit(bench, rewritten, tmp_path):
    judged(bench, tmp_path, rewritten)


def test_a_header_written_again_and_a_row_of_zeros_are_dropped_alike_in_memory_and_streamed(tmp_path):
    """A logger restarted, appending to its file: the header line written again (the clock running on, or going
    back). Measured at 4d50ebf: every verb exited (``column q1 holds 1 NaN/inf or non-numeric value(s)``). Now the
    line is dropped and said (:class:`RepeatedHeaderWarning`, naming its line), in memory and chunk by chunk alike,
    the rows as without it; a clock going back there splits the record as any restart; a line that is not the
    header stays an error naming its column. A lost frame written as a row of zeros (at 4d50ebf read as a sample,
    the case above 805x the plain fit) is a dropout, alike in memory and streamed; not in a file without torques
    (a planned trajectory's positions may start at the zero pose)."""
    from dynamics.models import build_model
    from estimation.data import BlankRowsWarning, NonFiniteError, RepeatedHeaderWarning
    from estimation.data.records import read_measurements, read_record
    from estimation.streaming.chunks import read_chunks, segment_sources
    from tests.test_unseen_robots import FRICTION, truth, urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(4.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    lines = (tmp_path / "clean.csv").read_text().rstrip("\n").split("\n")
    (tmp_path / "again.csv").write_text("\n".join([*lines[:401], lines[0], *lines[401:]]) + "\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        clean = read_measurements(tmp_path / "clean.csv", model=model)
        memory = read_measurements(tmp_path / "again.csv", model=model)
        chunks = list(read_chunks(tmp_path / "again.csv", model, chunk_size=250))
    said = {str(item.message) for item in caught if issubclass(item.category, RepeatedHeaderWarning)}
    assert said == {f"{tmp_path / 'again.csv'}: 1 line(s) repeat the header, first at line 402 (a logger restarted "
                    "and appended to the file): dropped; a clock that starts again there splits the record"}, said
    assert np.array_equal(memory.t, clean.t) and np.array_equal(memory.tau, clean.tau)
    assert np.array_equal(np.concatenate([chunk.t for chunk in chunks]), clean.t)
    assert np.array_equal(np.vstack([chunk.tau for chunk in chunks]), clean.tau)
    (tmp_path / "back.csv").write_text("\n".join([*lines[:401], lines[0], *lines[351:]]) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        segments = read_record(tmp_path / "back.csv", model=model)
        sources = segment_sources([tmp_path / "back.csv"], model, chunk_size=250)
    assert [len(segment.t) for segment in segments] == [400, 650] and len(sources) == 2, sources
    row = lines[201].split(",")  # a lost frame written as zeros, its time stamp kept
    (tmp_path / "zeros.csv").write_text("\n".join([*lines[:201], ",".join([row[0]] + ["0"] * (len(row) - 1)),
                                                    *lines[202:]]) + "\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        memory = read_measurements(tmp_path / "zeros.csv", model=model)
        chunks = list(read_chunks(tmp_path / "zeros.csv", model, chunk_size=250))
    said = {str(item.message) for item in caught if issubclass(item.category, BlankRowsWarning)}
    assert len(said) == 1 and "dropped 1 row(s)" in said.pop(), said
    kept = np.delete(np.arange(len(clean.t)), 200)
    assert np.array_equal(memory.as_recorded.t, clean.t[kept]) and np.array_equal(memory.as_recorded.tau,
                                                                                   clean.tau[kept])
    assert np.allclose(np.concatenate([chunk.t for chunk in chunks]), memory.t, rtol=0, atol=1e-12)
    assert np.allclose(np.vstack([chunk.tau for chunk in chunks]), memory.tau, rtol=0, atol=1e-12)
    positions = tmp_path / "planned.csv"  # a planned trajectory's positions, from the zero pose: nothing dropped
    table = pd.read_csv(tmp_path / "clean.csv")[["t", "q1", "q2", "q3"]]
    table.loc[:4, ["q1", "q2", "q3"]] = 0.0
    table.to_csv(positions, index=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (planned,) = read_record(positions, n_joints=3, require=("q",))
    assert not [item for item in caught if issubclass(item.category, BlankRowsWarning)] and len(planned.t) == 1000
    other = lines[0].replace("q1", "position")
    (tmp_path / "other.csv").write_text("\n".join([*lines[:401], other, *lines[401:]]) + "\n")
    with pytest.raises(NonFiniteError, match="column q1"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        read_measurements(tmp_path / "other.csv", model=model)


@pytest.mark.slow
def test_the_column_map_of_joints_named_with_spaces_is_said_as_a_shell_reads_it(tmp_path):
    """Columns named by joints whose names hold a space, a dot, an accent: read by name, and the warning's
    ``--columns`` option quoted so that a shell passes it whole (it said ``--columns q1=Schulter 1_position,…``
    at 4d50ebf, two words to a shell) and the option so read maps the columns as the reader did."""
    import shlex

    from dynamics.models import build_model
    from estimation.data.log_formats import JointNamedColumnsWarning, parse_column_map
    from estimation.data.records import read_record

    model = build_model(named_puma(), "internal")
    t = np.arange(0.0, 1.0, 0.01)
    table = pd.DataFrame({"t": t} | {f"{name}_position": (j + 1) * np.sin(t) for j, name in enumerate(NAMES)}
                         | {f"{name}_effort": -(j + 1.0) + 0 * t for j, name in enumerate(NAMES)})
    table.to_csv(tmp_path / "named.csv", index=False)
    with pytest.warns(JointNamedColumnsWarning) as caught:
        (segment,) = read_record(tmp_path / "named.csv", model=model, require=("tau",))
    message = str(caught[0].message)
    words = shlex.split(message[message.index("(--columns ") + 1:message.rindex(")")])
    assert words[0] == "--columns" and len(words) == 2, message
    assert parse_column_map(words[1])["q1"] == "Schulter 1_position", words
    assert parse_column_map(words[1])["tau3"] == "poignet_é_effort", words
    assert np.allclose(segment.q[:, 1], 2 * np.sin(t)) and np.all(segment.tau[:, 2] == -3.0)
