"""Simulated experiments: the forward-dynamics simulator, the servo-arm simulator, controllers, sensors and the effects the simulator applies; synthetic measurements straight from a model.

Modules: :mod:`~dynamics.simulation.controllers`, :mod:`~dynamics.simulation.effects`, :mod:`~dynamics.simulation.joint_effects`, :mod:`~dynamics.simulation.motor_effects`, :mod:`~dynamics.simulation.plant`, :mod:`~dynamics.simulation.plate_effects`, :mod:`~dynamics.simulation.sensors`, :mod:`~dynamics.simulation.servo_simulator`, :mod:`~dynamics.simulation.simulator`, :mod:`~dynamics.simulation.synthetic`.
"""
