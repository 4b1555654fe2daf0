"""Long records in bounded memory: records read chunk by chunk, their time base and periods, sums over many files (clusters), and the streamed identification and diagnosis.

Modules: :mod:`~estimation.streaming.candidate_screening`, :mod:`~estimation.streaming.chunks`, :mod:`~estimation.streaming.cluster`, :mod:`~estimation.streaming.covariance`, :mod:`~estimation.streaming.diagnosis`, :mod:`~estimation.streaming.diagnosis_candidates`, :mod:`~estimation.streaming.diagnosis_passes`, :mod:`~estimation.streaming.diagnosis_sums`, :mod:`~estimation.streaming.identification`, :mod:`~estimation.streaming.identification_covariance`, :mod:`~estimation.streaming.periods`, :mod:`~estimation.streaming.selection`, :mod:`~estimation.streaming.time_base`.
"""
