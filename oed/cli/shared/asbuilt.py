"""The options of the robot as built, for ``oed identify`` and ``oed diagnose`` (what they do:
:mod:`oed.workflows.asbuilt`)::

    --transmission FILE     JSON transmission (dynamics.transmission.transmission_from_json); default:
                            the URDF's <transmission> elements, or the built-in robot's (PUMA 560)
    --joint-offsets FILE    offsets added to the recorded joint positions (dynamics.transmission_files.read_joint_offsets),
                            and the joints' directions ("signs", "torque_signs": read_joint_directions)
    --min-speed V           rows slower than V (rad/s, m/s; joints and coupled motors) are at rest
    --rest drop|smooth      drop them (default) or smooth the Coulomb laws to tanh(v / V)
"""

from __future__ import annotations

import argparse


def add_asbuilt_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("the robot as built")
    group.add_argument("--transmission", help="transmission JSON (gear ratios, coupling matrix, torque constants); "
                       "default: the URDF's <transmission> elements or the built-in robot's")
    group.add_argument("--joint-offsets", metavar="FILE", help="offsets added to the recorded joint positions (rad, "
                       "or m): encoders zeroed elsewhere than the URDF; JSON {\"joint2\": -1.5708} (by name or number, "
                       "or a list) or CSV with columns joint,offset; a joint whose recorded direction is the URDF axis's opposite: "
                       "{\"signs\": {\"joint2\": -1}, \"torque_signs\": {\"joint2\": -1}} (q, dq, ddq and tau times "
                       "them; beside \"offsets\") or CSV columns sign,torque_sign; stored in the model file for oed "
                       "predict")
    group.add_argument("--min-speed", type=float, help="rows where a joint (or a coupled motor) moves slower than "
                       "this (rad/s or m/s) are at rest: dropped, or the Coulomb law smoothed (--rest)")
    group.add_argument("--rest", choices=("drop", "smooth"), default="drop",
                       help="with --min-speed: drop the rows at rest (default) or smooth Coulomb to tanh(v / V)")
