"""The servo-arm paper (Paiva et al.): the second-order joint model, its ERLS identification protocol, the output-error fit and the workflow's files.

Modules: :mod:`~estimation.servo.files`, :mod:`~estimation.servo.model`, :mod:`~estimation.servo.output_error`, :mod:`~estimation.servo.output_error_arm`, :mod:`~estimation.servo.output_error_covariance`, :mod:`~estimation.servo.output_error_model`, :mod:`~estimation.servo.protocol`.
"""
