"""The real Franka Panda log identified from MuJoCo Menagerie's Panda model (``--mjcf``) instead of the paper's URDF.

The same split, runs and plain least-squares reference as ``bench_real_robots.py --robots panda``; the robot is
the MJCF file given (``mujoco_menagerie/franka_emika_panda/panda.xml``, not in this repository: its meshes are
not read, only its bodies and joints), its 7 arm joints named and the fingers held fixed at 0. What changes
against the URDF run is the description's bodies (the consistent fit's prior) and nothing else; the plain fit
uses only the kinematics, so its figure says whether the two descriptions' kinematics agree.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_mjcf_panda.py --mjcf PATH/panda.xml [--runs default,diagnose]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_real_robots import DATA, RUNS, compare, panda, table

JOINTS = ",".join(f"joint{index}" for index in range(1, 8))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mjcf", type=Path, required=True, help="MuJoCo Menagerie's franka_emika_panda/panda.xml")
    parser.add_argument("--runs", default=",".join(run[0] for run in RUNS))
    args = parser.parse_args()
    if not DATA.is_dir():
        sys.exit(f"no real data at {DATA}")
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        case = panda(Path(folder))
        case.name = f"Franka Panda, robot from {args.mjcf.name} (MJCF)"
        case.robot = ["--mjcf", str(args.mjcf.resolve()), "--joint-names", JOINTS]
        outcome = compare(case, Path(folder), tuple(args.runs.split(",")))
        print("\n".join(table(case.name, outcome)) + f"\n({time.perf_counter() - started:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
