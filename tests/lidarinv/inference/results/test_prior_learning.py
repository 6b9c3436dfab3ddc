"""A parameter's posterior against its prior: contraction, KS distance, prior dominance."""

from dataclasses import replace

import numpy as np
import pytest
from tiny_results import tiny_result

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionResult, InversionSettings, build_problem
from lidarinv.inference.results.prior_learning import (
    PRIOR_DOMINATED_DISTANCE,
    prior_learning,
    support_prior_draws,
)


def test_a_posterior_that_is_its_prior_is_prior_dominated_and_a_pinned_one_is_not():
    rng = np.random.default_rng(0)
    prior = rng.uniform(0.0, 1.0, (4000, 2))
    posterior = np.column_stack([rng.uniform(0.0, 1.0, 3000), rng.normal(0.3, 0.02, 3000)])
    learning = prior_learning(posterior, prior, ["flat", "pinned"])
    flat, pinned = learning["flat"], learning["pinned"]
    assert flat["prior_dominated"] and not pinned["prior_dominated"]
    assert abs(flat["contraction"]) < 0.1 and flat["ks_distance"] < flat["ks_noise"]
    # a uniform on [0, 1] has variance 1/12: N(0.3, 0.02²) keeps 12·0.02² of it
    assert pinned["contraction"] == pytest.approx(1.0 - 12 * 0.02**2, abs=2e-3)
    assert pinned["prior_sd"] == pytest.approx(np.sqrt(1 / 12), rel=0.03)
    assert pinned["ks_distance"] > 0.6  # half the prior's mass lies beyond 0.3 ± 3 sd


def test_a_shift_counts_as_learning_only_beyond_the_monte_carlo_noise_of_few_samples():
    rng = np.random.default_rng(1)
    prior = rng.uniform(0.0, 1.0, (4000, 1))
    # a posterior density 0.4 + 1.2·x on [0, 1]: its CDF departs from the prior's by
    # 0.6·x(1 − x), 0.15 at x = 1/2
    u = rng.uniform(size=3000)
    shifted = ((-0.4 + np.sqrt(0.16 + 2.4 * u)) / 1.2)[:, None]
    many = prior_learning(shifted, prior, ["x"], ess={"x": 3000.0})["x"]
    few = prior_learning(shifted, prior, ["x"], ess={"x": 10.0})["x"]
    assert many["ks_distance"] == pytest.approx(0.15, abs=0.04)
    assert few["ks_distance"] == many["ks_distance"]
    assert few["ks_noise"] > 0.4 > 0.05 > many["ks_noise"]
    assert few["prior_dominated"] and not many["prior_dominated"]
    # the same posterior as its prior: dominated at any effective size
    same = rng.uniform(size=(3000, 1))
    assert prior_learning(same, prior, ["x"], ess={"x": 3000.0})["x"]["prior_dominated"]
    assert PRIOR_DOMINATED_DISTANCE < 0.15


def test_columns_that_do_not_match_the_names_are_refused_and_empty_ones_left_out():
    rng = np.random.default_rng(2)
    with pytest.raises(ValueError, match="one column per parameter"):
        prior_learning(rng.normal(size=(10, 2)), rng.normal(size=(10, 3)), ["a", "b"])
    posterior = np.column_stack([rng.normal(size=50), np.full(50, np.nan)])
    prior = np.column_stack([rng.normal(size=80), rng.normal(size=80)])
    assert list(prior_learning(posterior, prior, ["a", "b"])) == ["a"]
    constant = np.column_stack([rng.normal(size=80), np.ones(80)])
    assert list(prior_learning(prior, constant, ["a", "b"])) == ["a"]


def test_the_prior_draws_lie_in_the_posteriors_support():
    recipe = replace(SYNTHETIC_SHOTS["gedi-mixed"], gain=20000.0, noise_sigma=2.0)
    shot = synthetic_shot(recipe, np.random.default_rng(11), explicit=False, shot_id=7)
    bounded = replace(InversionSettings(discrepancy_model="observed"), favd_range=(0.05, 1.0))
    problem = build_problem(shot, bounded)
    rng = np.random.default_rng(3)
    draws = support_prior_draws(problem.log_posterior, problem.space, rng, size=600)
    assert 0 < draws.shape[0] < 600  # the FAVD range leaves some prior draws out
    assert np.all(np.isfinite(problem.log_posterior.log_prob(draws)))


def test_the_summary_names_the_prior_dominated_parameters_and_keeps_them_on_disk(tmp_path):
    result = tiny_result()
    rng = np.random.default_rng(4)
    prior = np.column_stack([rng.uniform(0, 1, 2000), rng.uniform(5, 40, 2000)])
    result.diagnostics["prior_learning"] = prior_learning(
        result.samples[:, :2], prior, ["cover", "top_height"]
    )
    assert result.prior_dominated == []
    result.diagnostics["prior_learning"]["cover"]["prior_dominated"] = True
    assert result.prior_dominated == ["cover"]
    lines = [line for line in result.summary_table().splitlines() if "posterior ≈ prior" in line]
    assert len(lines) == 1 and "cover (KS" in lines[0] and "top_height" not in lines[0]
    assert result.summary_row()["prior_dominated"] == "cover"
    result.save(tmp_path / "r.h5")
    back = InversionResult.load(tmp_path / "r.h5")
    assert back.prior_dominated == ["cover"]
    assert tiny_result().prior_dominated == []  # a result without the comparison
