"""Simulated experiments: the forward-dynamics simulator, the servo-arm simulator, controllers, sensors and the effects the simulator applies.

Modules: :mod:`~dynamics.simulation.controllers`, :mod:`~dynamics.simulation.effects`, :mod:`~dynamics.simulation.joint_effects`, :mod:`~dynamics.simulation.motor_effects`, :mod:`~dynamics.simulation.plant`, :mod:`~dynamics.simulation.plate_effects`, :mod:`~dynamics.simulation.sensors`, :mod:`~dynamics.simulation.servo_simulator`, :mod:`~dynamics.simulation.simulator`.
"""
