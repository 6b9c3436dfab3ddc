"""The stopping rule watches the reported quantities in physical units, not the sampler's
joint coordinates (cover with PAI, the ground with the understory)."""

import numpy as np
import pytest

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, build_problem
from lidarinv.inference.results.reported import reported_monitor


@pytest.fixture(scope="module")
def problem():
    shot = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(3))
    return build_problem(shot, InversionSettings(cohorts=1))


def test_sampled_quantities_are_monitored_in_physical_units(problem):
    space = problem.space
    rng = np.random.default_rng(4)
    x = space.sample_prior(rng, 40)
    u = space.to_unbounded(x)
    chain = u.reshape(10, 4, -1)
    blobs = np.zeros((10, 4, len(problem.log_posterior.blob_names)))
    watched = reported_monitor(space, problem.log_posterior.blob_names)(chain, blobs)
    for name in ("cover", "ground_elevation", "top_height"):
        column = space.names.index(name)
        np.testing.assert_allclose(watched[name], x[:, column].reshape(10, 4), rtol=1e-9)
    # the joint cover–PAI coordinate is not cover: the raw column would have misled the rule
    assert not np.allclose(chain[..., space.names.index("cover")], watched["cover"])
