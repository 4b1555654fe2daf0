"""A regression corpus for the diagnosis loop: simulated cases whose truth is known, each with what the loop must
name, how close to the noise floor it must end and how close its estimates must come to the truth.

The cases are data (:mod:`tests.corpus.cases`); the tests read them (``test_library_cases``, ``test_user_loops``,
``test_candidate_order``). A case that misses its target today is a strict ``xfail`` holding the measured figures,
so that the day it is met the corpus says so.
"""
