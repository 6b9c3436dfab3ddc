"""Property tests of the shot log-posterior: no NaN, −inf outside the support."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, build_problem


@pytest.fixture(scope="module", params=[True, False], ids=["gain-marginalised", "gain-sampled"])
def problem(request):
    obs = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(4), explicit=False)
    return build_problem(obs, InversionSettings(marginalise_gain=request.param))


anything = st.floats(allow_nan=True, allow_infinity=True, width=64)
#: Longest parameter vector (13 free with the gain sampled); rows are cut to the space's.
WIDEST = 13


@settings(max_examples=60, deadline=None)
@given(fractions=st.lists(st.floats(0.0, 1.0), min_size=WIDEST, max_size=WIDEST))
def test_inside_the_prior_box_log_posterior_is_finite_or_invalid(problem, fractions):
    space = problem.space
    x = np.array(
        [p.prior.lower + f * (p.prior.upper - p.prior.lower) for p, f in zip(space.free, fractions)]
    )
    terms = problem.log_posterior.evaluate(x[None, :])
    value = terms.log_posterior[0]
    assert not np.isnan(value)
    values = space.values(x[None, :])
    if (
        np.isfinite(space.log_prior(x[None, :])[0])
        and problem.log_posterior.mapping.valid(values)[0]
    ):
        assert np.isfinite(value)
        assert np.all(np.isfinite(terms.blobs[0]))


@settings(max_examples=60, deadline=None)
@given(row=st.lists(anything, min_size=WIDEST, max_size=WIDEST))
def test_any_input_gives_a_number_or_minus_inf(problem, row):
    value = problem.log_posterior.log_prob(np.array([row[: problem.space.ndim]]))[0]
    assert not np.isnan(value) and value != np.inf


@settings(max_examples=40, deadline=None)
@given(row=st.lists(st.floats(-800, 800), min_size=WIDEST, max_size=WIDEST))
def test_unbounded_coordinates_never_give_nan(problem, row):
    out = problem.log_posterior(np.array([row[: problem.space.ndim]]))
    assert not np.isnan(out[0, 0]) and out[0, 0] != np.inf


@settings(max_examples=30, deadline=None)
@given(index=st.integers(0, WIDEST - 1), beyond=st.floats(1e-9, 1e6), low=st.booleans())
def test_beyond_any_prior_bound_is_minus_inf(problem, index, beyond, low):
    space = problem.space
    index %= space.ndim
    x = np.array([[0.5 * (p.prior.lower + p.prior.upper) for p in space.free]])
    p = space.free[index].prior
    x[0, index] = p.lower - beyond if low else p.upper + beyond
    assert problem.log_posterior.log_prob(x)[0] == -np.inf


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e9])
def test_float32_and_extreme_gain_observations_give_numbers(scale):
    obs = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(9), explicit=False)
    obs = replace(obs, samples=(obs.samples * scale).astype(np.float32))
    problem = build_problem(obs)
    rng = np.random.default_rng(1)
    x = problem.space.sample_prior(rng, 64)
    values = problem.log_posterior.log_prob(x)
    assert not np.any(np.isnan(values)) and np.any(np.isfinite(values))
    assert problem.space.by_name["gain"].prior.upper > 1e-3 * scale
