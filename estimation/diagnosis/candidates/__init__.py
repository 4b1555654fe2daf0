"""The diagnosis's candidates: fitting every candidate effect against the current model, effects on joint
combinations (coupled joints, motors), and the delay between torques and motion as a candidate.

Modules: :mod:`~estimation.diagnosis.candidates.coupling`, :mod:`~estimation.diagnosis.candidates.delay`,
:mod:`~estimation.diagnosis.candidates.delay_search`, :mod:`~estimation.diagnosis.candidates.projected_columns`,
:mod:`~estimation.diagnosis.candidates.trials`.
"""
