"""How far another draw of the discrepancy's realisations moves the quantiles: none where
every realisation is the same, less from many realisations than from few, and recorded in
an inversion's result."""

import numpy as np
import pytest

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, SamplerSettings, build_problem, invert_shot
from lidarinv.inference.invert import one_blas_thread
from lidarinv.inference.passes.realisations import realisation_residuals
from lidarinv.inference.results import realisation_spread as spread_module
from lidarinv.inference.results.realisation_spread import DiscrepancyDraws, realisation_spread
from lidarinv.inference.results.result import InversionResult
from lidarinv.inference.settings import RealisationSettings


@pytest.fixture(scope="module")
def shot():
    return synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(11))


@pytest.fixture(scope="module")
def setting(shot):
    """The problem, 48 realisation residuals about the truth and rows near it."""
    problem = build_problem(shot, InversionSettings(correlated_noise=False))
    truth = np.array([shot.truth[name] for name in problem.space.names])
    rng = np.random.default_rng(4)
    x_draws = truth * rng.uniform(0.95, 1.05, (48, truth.size))
    residuals = realisation_residuals(problem.log_posterior, problem.instrument, x_draws, rng)
    x = truth * rng.uniform(0.97, 1.03, (300, truth.size))
    return problem, residuals, x


def _spread(problem, residuals, x, seed=0, extra=None):
    draws = DiscrepancyDraws(residuals, 0.3, np.full(residuals.shape[1], 1.0))
    post = problem.log_posterior
    post = post.with_likelihood(post.likelihood.with_fixed_discrepancy(draws.covariance()))
    columns = {name: x[:, problem.space.names.index(name)] for name in ("top_height", "cover")}
    columns.update(extra or {})
    with one_blas_thread():  # as in an inversion: threaded eigh of small matrices crawls
        return realisation_spread(post, draws, x, columns, np.random.default_rng(seed), 16, 300)


def test_identical_realisations_leave_nothing_to_resample(setting):
    """Every resample of K equal residuals is the same covariance: the weights are even and
    the quantiles do not move."""
    problem, residuals, x = setting
    same = np.repeat(residuals[:1], 12, axis=0)
    found = _spread(problem, same, x)
    assert found.weight_fraction == pytest.approx(1.0)
    assert all(v == pytest.approx(0.0, abs=1e-12) for v in found.spread.values())


def test_few_realisations_move_the_quantiles_more_than_many(setting):
    """The bootstrap's spread is the sampling error of the covariance: 6 realisations give
    a covariance that moves the posterior more than 48 do."""
    problem, residuals, x = setting
    few, many = _spread(problem, residuals[:6], x), _spread(problem, residuals, x)
    assert max(few.spread.values()) > 1.5 * max(many.spread.values())
    assert 0.0 < few.weight_fraction < many.weight_fraction <= 1.0


def test_a_quantity_without_finite_samples_has_no_spread(setting):
    """A column the result could not compute (NaN throughout) gets NaN, and the others
    their spread."""
    problem, residuals, x = setting
    found = _spread(problem, residuals, x, extra={"rh98_footprint": np.full(len(x), np.nan)})
    assert np.isnan(found.spread["rh98_footprint"])
    assert np.isfinite(found.spread["top_height"]) and np.isfinite(found.spread["cover"])


def test_the_spread_needs_two_resamples(setting):
    problem, residuals, x = setting
    draws = DiscrepancyDraws(residuals, 0.3, np.zeros(residuals.shape[1]))
    with pytest.raises(ValueError, match="at least 2 resamples"):
        realisation_spread(problem.log_posterior, draws, x, {}, np.random.default_rng(0), 1)
    with pytest.raises(ValueError, match="resamples"):
        RealisationSettings(resamples=1)


def test_an_inversion_reports_the_spread_and_flags_a_large_one(shot, tmp_path, monkeypatch):
    """The result holds each reported quantity's spread, its summary says it, it survives
    a round trip through HDF5, and a spread beyond the flag's threshold is flagged."""
    monkeypatch.setattr(spread_module, "FLAG_SPREAD_SD", 0.0)  # every spread is too large
    quick = SamplerSettings(max_steps=100, check_every=100, candidates=64, starts=2, polish=1)
    settings = InversionSettings(
        realisations=RealisationSettings(count=16, resamples=4, first_fraction=1.0),
        sampler=quick,
        cohorts=1,
    )
    result = invert_shot(shot, settings, rng=np.random.default_rng(2))
    found = result.diagnostics["realisation_spread"]
    assert found["resamples"] == 4 and 0.0 < found["weight_fraction"] <= 1.0
    assert {"top_height", "cover"} <= set(found["spread"])
    assert all(np.isfinite(v) and v >= 0 for v in found["spread"].values())
    assert "over the discrepancy's 16 of 16 realisations" in result.summary_table()
    assert result.summary_row()["max_realisation_spread"] == max(found["spread"].values())
    assert any("raise RealisationSettings.count" in flag for flag in result.flags)
    result.save(tmp_path / "r.h5")
    loaded = InversionResult.load(tmp_path / "r.h5").diagnostics
    assert loaded["realisation_spread"] == found
    assert loaded["realisations"] == result.diagnostics["realisations"]
    none = InversionSettings(
        realisations=RealisationSettings(count=16, resamples=0, first_fraction=1.0),
        sampler=quick,
        cohorts=1,
    )
    quiet = invert_shot(shot, none, rng=np.random.default_rng(2))
    assert "realisation_spread" not in quiet.diagnostics
    np.testing.assert_array_equal(quiet.samples, result.samples)  # measured after sampling
