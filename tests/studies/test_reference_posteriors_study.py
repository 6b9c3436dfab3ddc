"""The long reference runs (``studies/reference_posteriors.py``) last the steps asked."""

import numpy as np
from reference_posteriors import long_run_settings

from lidarinv.inference.model.priors import Uniform
from lidarinv.inference.model.space import Parameter, ParameterSpace
from lidarinv.inference.sampling import SamplerSettings, run_sampler

SPACE = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(2))


def gaussian(u):
    """A standard normal in two coordinates, with their sum as a blob."""
    x, log_jacobian = SPACE.from_unbounded(u)
    return np.column_stack([-0.5 * np.sum(x * x, axis=1) + log_jacobian, x.sum(axis=1)])


def test_a_long_run_is_ended_neither_by_the_rule_nor_by_importance_draws():
    quick = SamplerSettings(n_walkers=16, max_steps=600, check_every=100)
    early = run_sampler(gaussian, SPACE, np.random.default_rng(0), quick)
    assert early.importance is not None and early.chain.shape[0] < 600  # what a default does
    run = run_sampler(gaussian, SPACE, np.random.default_rng(0), long_run_settings(quick, 600))
    assert run.importance is None and run.importance_tries == []
    assert run.chain.shape[0] == 600 and not run.converged
