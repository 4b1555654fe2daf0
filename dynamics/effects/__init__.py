"""Extra regressor columns beyond rigid-body dynamics: linear effects (friction, offsets, armature), shaped effects, motor-side and joint-combination effects, and effect specs as users type them.

Modules: :mod:`~dynamics.effects.combination_shapes`, :mod:`~dynamics.effects.joint_lists`, :mod:`~dynamics.effects.linear`, :mod:`~dynamics.effects.motor`, :mod:`~dynamics.effects.shaped`, :mod:`~dynamics.effects.specs`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "Armature": "dynamics.effects.linear",
    "CombinationEffect": "dynamics.effects.motor",
    "CoulombFriction": "dynamics.effects.linear",
    "DirectionalViscousFriction": "dynamics.effects.linear",
    "Effect": "dynamics.effects.linear",
    "EffectSpecError": "dynamics.effects.joint_lists",
    "FRICTION_LAWS": "dynamics.effects.shaped",
    "JointOffset": "dynamics.effects.linear",
    "KINDS": "dynamics.effects.motor",
    "POSITIVE_EFFECTS": "dynamics.effects.linear",
    "PositionRipple": "dynamics.effects.shaped",
    "ShapeBoundsError": "dynamics.effects.shaped",
    "ShapeKind": "dynamics.effects.shaped",
    "ShapeParameter": "dynamics.effects.shaped",
    "ShapedPerJointEffect": "dynamics.effects.shaped",
    "ShapedStribeckFriction": "dynamics.effects.shaped",
    "SigmoidFriction": "dynamics.effects.shaped",
    "Spring": "dynamics.effects.linear",
    "StribeckFriction": "dynamics.effects.linear",
    "TanhCombinationCoulomb": "dynamics.effects.combination_shapes",
    "TanhCoulombFriction": "dynamics.effects.shaped",
    "ViscousFriction": "dynamics.effects.linear",
    "WRENCH_CHANNELS": "dynamics.effects.linear",
    "WrenchOffset": "dynamics.effects.linear",
    "build_effects": "dynamics.effects.specs",
    "combination_from_label": "dynamics.effects.motor",
    "combination_row": "dynamics.effects.combination_shapes",
    "effect_spec": "dynamics.effects.specs",
    "is_shaped": "dynamics.effects.shaped",
    "motor_effects": "dynamics.effects.motor",
    "pair_combinations": "dynamics.effects.motor",
    "parse_effects": "dynamics.effects.linear",
    "parse_joint_list": "dynamics.effects.joint_lists",
    "shape_parameters": "dynamics.effects.shaped",
    "split_joints": "dynamics.effects.joint_lists",
    "start_grid": "dynamics.effects.shaped",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
