"""Importance draws from a t fitted to the chain: weights, their judgement, resampling."""

import arviz as az
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lidarinv.inference.sampling.importance import (
    ImportanceSettings,
    importance_sample,
    systematic_resample,
    weighted_diagnostics,
    weighted_ess,
)
from lidarinv.inference.sampling.stopping import StopRule, coordinates_monitor

#: A correlated 2-D Gaussian posterior in closed form.
MEAN = np.array([1.0, -2.0])
COV = np.array([[1.0, 0.8], [0.8, 2.0]])


def gaussian_posterior(u):
    d = u - MEAN
    log_post = -0.5 * np.einsum("ij,ij->i", d @ np.linalg.inv(COV), d)
    return np.column_stack([log_post, u[:, 0] + u[:, 1]])  # one blob: the sum


def heavy_posterior(u):
    """A Student t of 1.5 degrees of freedom: tails no t fitted to a narrow cloud covers."""
    return (-1.75 * np.log1p(np.sum(u * u, axis=1) / 1.5))[:, None]


MONITOR = coordinates_monitor(["x0", "x1"])


def test_equal_weights_count_every_draw_and_one_weight_counts_one():
    values = np.random.default_rng(0).standard_normal(1000)
    assert weighted_ess(values, np.full(1000, 1e-3)) == pytest.approx(1000)  # 1 / Σ w²
    weights = np.full(1000, 1e-9)
    weights[0] = 1.0
    assert weighted_ess(values, weights / weights.sum()) < 1.01


def test_gaussian_draws_pass_and_match_the_closed_form():
    rng = np.random.default_rng(1)
    points = rng.multivariate_normal(MEAN, COV, size=3000)  # a chain that has converged
    run = importance_sample(
        gaussian_posterior, points, MONITOR, StopRule(), ImportanceSettings(), rng, step=200
    )
    assert run.passed and run.khat < 0.5, run.shortfalls
    assert run.ess > 0.5 * ImportanceSettings().draws  # a wider t than the posterior
    error = np.sqrt(np.diag(COV) / run.ess)
    np.testing.assert_array_less(np.abs(run.u.mean(axis=0) - MEAN), 5 * error)
    np.testing.assert_allclose(np.cov(run.u.T), COV, rtol=0.15)
    np.testing.assert_allclose(run.blobs[:, 0], run.u.sum(axis=1))  # rows stay together
    assert np.all(np.isfinite(run.log_prob))


def test_quantile_error_of_equal_weights_is_arviz_quantile_mcse():
    """Independent draws of equal weight: the quantiles' Monte Carlo error is ArviZ's for
    independent draws, and both ESS are the draws."""
    values = np.random.default_rng(2).standard_normal(4000)
    d = weighted_diagnostics(values, np.full(values.size, 1 / values.size))
    assert d["ess_bulk"] == pytest.approx(values.size) and d["ess_tail"] == pytest.approx(4000)
    reference = max(az.mcse(values[None], method="quantile", prob=q) for q in (0.05, 0.5, 0.95))
    assert d["quantile_mcse"] == pytest.approx(reference / np.std(values), rel=0.2)
    assert np.isnan(d["rhat"]) and np.isnan(d["tau"])  # not a chain's diagnostics
    assert weighted_diagnostics(np.ones(10), np.full(10, 0.1))["tau"] == 0  # does not vary


def test_more_draws_are_made_where_only_their_number_falls_short():
    """256 draws cannot reach ESS 1000: batches of 256 more are made from the same t until
    they do, within ``max_draws`` and the chain's evaluations so far (``budget``); the
    result keeps 256 of them, resampled."""
    rng = np.random.default_rng(6)
    points = rng.multivariate_normal(MEAN, COV, size=3000)
    few = ImportanceSettings(draws=256, max_draws=256)
    capped = importance_sample(gaussian_posterior, points, MONITOR, StopRule(), few, rng, 200)
    assert not capped.passed and all("ESS" in s for s in capped.shortfalls)
    more = ImportanceSettings(draws=256, max_draws=4096)
    run = importance_sample(gaussian_posterior, points, MONITOR, StopRule(), more, rng, 200)
    assert run.passed and run.ess >= StopRule().ess_min and len(run.u) == 256
    assert 256 < run.made < 4096 and run.made % 256 == 0  # it stopped once the ESS sufficed
    budgeted = importance_sample(
        gaussian_posterior, points, MONITOR, StopRule(), more, rng, 8, budget=1000
    )  # a chain of 8 steps of 125 walkers: ~1000 draws would not reach the ESS either
    assert budgeted.made == 512 and not budgeted.passed  # a batch of each t, then given up


def test_a_t_fitted_again_to_its_weighted_draws_reaches_the_ess_sooner():
    """Walkers still narrow and off-centre: from their t, 12 288 draws fall short of the
    ESS; a t fitted again to those draws' weights reaches it within as many again."""
    rng = np.random.default_rng(0)
    points = rng.multivariate_normal(MEAN + 1.0, 0.3 * COV, size=3000)
    runs = {}
    for refits in (0, 1):
        settings = ImportanceSettings(max_draws=12288, refits=refits)
        runs[refits] = importance_sample(
            gaussian_posterior, points, MONITOR, StopRule(), settings, np.random.default_rng(1), 200
        )
    assert not runs[0].passed and all("ESS" in s for s in runs[0].shortfalls)
    assert runs[1].passed and runs[0].made < runs[1].made <= 2 * 12288, runs[1].shortfalls
    np.testing.assert_array_less(np.abs(runs[1].u.mean(axis=0) - MEAN), 0.15)
    np.testing.assert_allclose(np.cov(runs[1].u.T), COV, rtol=0.2)


def test_a_proposal_too_narrow_for_heavy_tails_fails_on_khat():
    rng = np.random.default_rng(4)
    points = 0.1 * rng.standard_normal((3000, 2))  # walkers that have not spread out yet
    run = importance_sample(
        heavy_posterior, points, MONITOR, StopRule(), ImportanceSettings(), rng, step=200
    )
    assert not run.passed
    assert any("Pareto k̂" in s for s in run.shortfalls)


def test_a_singular_cloud_gives_no_proposal():
    points = np.column_stack([np.arange(50.0), np.arange(50.0)])  # on a line
    rng = np.random.default_rng(5)
    tried = importance_sample(
        gaussian_posterior, points, MONITOR, StopRule(), ImportanceSettings(), rng, 200
    )
    assert tried is None


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.0, 10.0), min_size=2, max_size=40), st.integers(0, 2**32 - 1))
def test_systematic_resampling_keeps_each_draw_within_one_of_its_share(raw, seed):
    weights = np.asarray(raw) + 1e-3
    weights /= weights.sum()
    counts = np.bincount(systematic_resample(weights, np.random.default_rng(seed)),
                         minlength=weights.size)  # fmt: skip
    assert counts.sum() == weights.size
    assert np.all(np.abs(counts - weights.size * weights) < 1 + 1e-9)


def test_settings_refuse_what_cannot_work():
    with pytest.raises(ValueError, match="draws"):
        ImportanceSettings(draws=-1)
    with pytest.raises(ValueError, match="max_draws"):
        ImportanceSettings(draws=4096, max_draws=1024)
    with pytest.raises(ValueError, match="dof"):
        ImportanceSettings(dof=2.0)
    with pytest.raises(ValueError, match="refits"):
        ImportanceSettings(refits=-1)
