"""Extra regressor columns beyond rigid-body dynamics: linear effects (friction, offsets, armature), shaped effects, motor-side and joint-combination effects, and effect specs as users type them.

Modules: :mod:`~dynamics.effects.combination_shapes`, :mod:`~dynamics.effects.joint_lists`, :mod:`~dynamics.effects.linear`, :mod:`~dynamics.effects.motor`, :mod:`~dynamics.effects.shaped`, :mod:`~dynamics.effects.specs`.
"""
