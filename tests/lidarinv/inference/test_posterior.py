"""The shot log-posterior: −inf handling, recovery of a known stand, result round trip, CLI."""

from dataclasses import replace

import numpy as np
import pytest

from lidarinv.cli import main
from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import (
    InversionResult,
    InversionSettings,
    SamplerSettings,
    build_problem,
    invert_shot,
)

# ρv/ρg and the understory known: the canopy structure is then well identified
KNOWN = {"rho_ratio": 1.5, "understory_lai": 0.3, "understory_height": 1.0}
QUICK = InversionSettings(
    sampler=SamplerSettings(max_steps=3000, check_every=500),
    priors={name: {"fixed": value} for name, value in KNOWN.items()},
    discrepancy_model="observed",  # the shot is the expected waveform: no arrangement to model
)


@pytest.fixture(scope="module")
def shot():
    recipe = replace(SYNTHETIC_SHOTS["gedi-mixed"], gain=20000.0, noise_sigma=2.0)
    return synthetic_shot(recipe, np.random.default_rng(11), explicit=False, shot_id=7)


@pytest.fixture(scope="module")
def problem(shot):
    return build_problem(shot, QUICK)


@pytest.fixture(scope="module")
def result(shot):
    return invert_shot(shot, QUICK, rng=np.random.default_rng(2))


def _truth_row(problem, shot):
    return np.array([[shot.truth[name] for name in problem.space.names]])


def test_truth_has_a_finite_posterior_and_blobs(problem, shot):
    terms = problem.log_posterior.evaluate(_truth_row(problem, shot))
    assert np.isfinite(terms.log_posterior[0])
    rh50, rh98 = terms.blobs[0, :2]
    assert 0 < rh50 < rh98 < shot.truth["top_height"]


def test_invalid_and_extreme_parameters_give_minus_inf_never_nan(problem, shot):
    post, space = problem.log_posterior, problem.space
    truth = _truth_row(problem, shot)[0]
    rows = []
    for i, p in enumerate(space.free):
        for value in (p.prior.lower, p.prior.upper, p.prior.lower - 1.0, p.prior.upper * 10 + 1):
            row = truth.copy()
            row[i] = value
            rows.append(row)
    for value in (np.nan, np.inf, -np.inf, 1e300):
        rows.append(np.full_like(truth, value))
    out = post.log_prob(np.array(rows))
    assert not np.any(np.isnan(out))
    assert np.all((out == -np.inf) | np.isfinite(out))
    beyond = np.array(rows[2::4][: space.ndim] + rows[3::4][: space.ndim])
    assert np.all(post.log_prob(beyond) == -np.inf)
    # the sampler's entry point in unbounded coordinates: extremes are finite or −inf
    u = np.vstack([np.full(space.ndim, 700.0), np.full(space.ndim, -700.0), np.zeros(space.ndim)])
    values = post(u)[:, 0]
    assert not np.any(np.isnan(values))


def test_noise_held_at_the_shot_estimates_when_not_sampled(shot):
    problem = build_problem(shot, replace(QUICK, sample_noise=False))
    space, analysis = problem.space, problem.analysis
    assert "baseline" not in space.names and "noise_sigma" not in space.names
    assert space.by_name["baseline"].fixed == pytest.approx(analysis.noise_mean)
    assert space.by_name["noise_sigma"].fixed == pytest.approx(analysis.noise_sigma)
    # the estimates are those of the simulated noise (baseline 50 DN, σ 2 DN)
    assert abs(analysis.noise_mean - 50.0) < 0.5 and abs(analysis.noise_sigma - 2.0) < 0.3


def test_favd_range_excludes_only_rows_outside_it(shot, tmp_path):
    path = tmp_path / "priors.toml"
    path.write_text("[favd]\nlower = 0.05\nupper = 3.0\n[rho_ratio]\nfixed = 1.5\n")
    bounded = InversionSettings.from_priors_file(path)
    assert bounded.favd_range == (0.05, 3.0)
    free = build_problem(shot, replace(bounded, favd_range=None)).log_posterior
    post = build_problem(shot, bounded).log_posterior
    x = post.space.sample_prior(np.random.default_rng(3), 400)
    favd = free.evaluate(x).blobs[:, list(free.blob_names).index("favd")]
    inside = (favd >= 0.05) & (favd <= 3.0)
    assert 0 < inside.sum() < inside.size
    np.testing.assert_array_equal(post.log_prob(x)[inside], free.log_prob(x)[inside])
    assert np.all(post.log_prob(x)[~inside & np.isfinite(favd)] == -np.inf)


def test_posterior_recovers_the_stand(result, shot):
    summary = result.summary()
    names = ("top_height", "ground_elevation", "cover", "pai", "crown_length_ratio", "lai")
    for name in (*names, "cone_fraction", "gain"):
        row = summary[name]
        assert row["p05"] <= shot.truth[name] <= row["p95"], (name, row, shot.truth[name])
    assert summary["top_height"]["p95"] - summary["top_height"]["p05"] < 4.0
    assert result.profile.shape == (5, result.profile_heights.size)
    assert np.all(np.diff(result.predictive, axis=0) >= -1e-9)  # quantile rows ordered


def test_result_round_trip(result, tmp_path):
    path = tmp_path / "posterior.h5"
    result.save(path, name="shot_7")
    back = InversionResult.load(path, name="shot_7")
    assert back.shot_id == 7
    assert back.parameter_names == result.parameter_names
    np.testing.assert_array_equal(back.samples, result.samples)
    np.testing.assert_array_equal(back.derived["rh98"], result.derived["rh98"])
    assert back.summary() == result.summary()
    assert back.converged == result.converged and back.flags == result.flags
    assert back.truth["top_height"] == pytest.approx(result.truth["top_height"])
    row = back.summary_row()
    assert row["shot_id"] == "7" and "cover_median" in row and "rh98_p95" in row
    with pytest.raises(ValueError, match="no posterior group"):
        InversionResult.load(path, name="shot_8")


def test_shot_without_ground_peak_is_refused_clearly(shot):
    flat = replace(shot, samples=np.full(shot.n_bins, shot.truth["baseline"]) + 0.0)
    flat.samples[::2] += 1.0  # noise only
    with pytest.raises(ValueError, match="shot 7"):
        build_problem(flat)


def test_cli_invert_example_writes_posterior_and_plots(tmp_path, capsys):
    out = tmp_path / "post.h5"
    code = main(
        ["invert", "--example", "gedi-mixed", "--max-steps", "200", "--walkers", "28",
         "--cohorts", "1", "-o", str(out), "--plots", str(tmp_path / "plots"), "--quiet"]
    )  # fmt: skip
    text = capsys.readouterr().out
    assert code == 0, text
    assert "top_height" in text and "NOT CONVERGED" in text
    assert "MAP search and discrepancy simulation" in text  # the default discrepancy
    assert InversionResult.load(out, name="shot_gedi-mixed").samples.shape[1] == 13
    assert len(list((tmp_path / "plots").glob("*.png"))) == 3


def test_cli_invert_needs_one_source(tmp_path, capsys):
    assert main(["invert", "-o", str(tmp_path / "x.h5")]) == 2
    assert "--example" in capsys.readouterr().err
