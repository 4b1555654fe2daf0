"""The next experiment, designed from what the experiments already run left uncertain.

- :mod:`oed.sequential.jacobian`: the identified model's noise-weighted Jacobian in all its parameters (shapes included);
- :mod:`oed.sequential.prior`: the records' Fisher information under it;
- :mod:`oed.sequential.criteria`: D-, Ds- and worst-relative optimality (a ``--focus`` group) on the posterior
  information;
- :mod:`oed.sequential.starts`: screened starts, with slowed joints among the candidates;
- :mod:`oed.sequential.problem`: the excitation design problem with that prior and criterion;
- :mod:`oed.sequential.next_experiment`: one call, with the predicted standard deviations;
- :mod:`oed.sequential.discrimination`: the experiment that best tells two rival models apart;
- :mod:`oed.sequential.rivals`: the rival, from a model file or the runner-up a diagnosis kept;
- :mod:`oed.sequential.figure`: the new trajectory beside the old ones, at low speed.
"""
