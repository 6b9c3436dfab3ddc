"""Figures a scientist can trust: a posterior predictive that includes the noise, the
floor and saturation marked and explained, labelled truths, titles that state their
quantiles and do not overlap, units written one way."""

from dataclasses import replace

import numpy as np
import pytest
from tiny_results import tiny_result

from lidarinv.inference.likelihood.gaussian import ShotLikelihood
from lidarinv.inference.results.collect import fit_statistics
from lidarinv.inference.results.plots import corner_plot, predictive_plot
from lidarinv.inference.shot import WindowData
from lidarinv.plotting import unit_label


def _likelihood(
    n_bins, floor=np.nan, saturation=np.nan, censored=None, fixed=None, eta=0.0, noise=None
):
    censored = np.zeros(n_bins, bool) if censored is None else censored
    data = WindowData(
        axis=np.arange(n_bins, dtype=float),
        samples=np.zeros(n_bins),
        censored=censored,
        saturated=np.zeros(n_bins, bool),
        floor=floor,
        saturation=saturation,
    )
    return ShotLikelihood(data, discrepancy=eta, fixed_discrepancy=fixed, noise_correlation=noise)


def test_replicated_observations_carry_the_likelihoods_variance():
    rng = np.random.default_rng(3)
    n, bins = 40_000, 5
    signal = np.tile(np.linspace(0.0, 0.02, bins), (n, 1))
    values = {"gain": np.full(n, 1000.0), "baseline": np.full(n, 50.0),
              "noise_sigma": np.full(n, 2.0)}  # fmt: skip
    covariance = np.diag(np.arange(bins, dtype=float)) + 0.5  # a discrepancy between bins
    draws, _, _ = _likelihood(bins, fixed=covariance).replicate(signal, values, rng)
    mean = 50.0 + 1000.0 * signal[0]
    np.testing.assert_allclose(draws.mean(axis=0), mean, atol=0.05)
    expected_sd = np.sqrt(4.0 + np.diag(covariance))  # σn² + the discrepancy's diagonal
    np.testing.assert_allclose(draws.std(axis=0), expected_sd, rtol=0.02)
    # the discrepancy is correlated between bins as simulated, not drawn bin by bin
    np.testing.assert_allclose(np.cov(draws.T), 4.0 * np.eye(bins) + covariance, atol=0.1)
    # a discrepancy proportional to the model: (η a W)²
    per_row, _, _ = _likelihood(bins, eta=0.2).replicate(signal, values, rng)
    np.testing.assert_allclose(
        per_row.std(axis=0), np.sqrt(4.0 + (0.2 * 1000.0 * signal[0]) ** 2), rtol=0.02
    )


def test_replicated_read_noise_is_correlated_as_the_likelihood_takes_it():
    from lidarinv.inference.likelihood.ar_noise import AutoregressiveNoise

    rng = np.random.default_rng(4)
    n, bins = 20_000, 12
    ar = AutoregressiveNoise.matching_integrated_time(0.8 ** np.arange(40))
    like = _likelihood(bins, fixed=np.zeros(bins), noise=ar)
    assert like.holds_noise  # the read noise is whitened in the likelihood
    values = {"gain": np.ones(n), "baseline": np.zeros(n), "noise_sigma": np.full(n, 2.0)}
    draws, _, _ = like.replicate(np.zeros((n, bins)), values, rng)
    np.testing.assert_allclose(draws.std(axis=0), 2.0, rtol=0.03)
    lag1 = np.mean(draws[:, 1:] * draws[:, :-1]) / 4.0
    assert lag1 == pytest.approx(ar.autocorrelation(2)[1], abs=0.02)


def test_replicated_observations_stop_at_the_floor_and_the_digitiser_maximum():
    rng = np.random.default_rng(4)
    n, bins = 2000, 4
    values = {"gain": np.full(n, 100.0), "baseline": np.full(n, 10.0),
              "noise_sigma": np.full(n, 3.0)}  # fmt: skip
    censored = np.array([True, False, False, False])
    post = _likelihood(bins, floor=9.0, saturation=12.0, censored=censored)
    draws, _, _ = post.replicate(np.zeros((n, bins)), values, rng)
    assert draws.min() == 9.0 and draws.max() == 12.0
    assert np.mean(draws == 12.0) == pytest.approx(1 - 0.7475, abs=0.02)  # P(N(10, 3) > 12)


def _texts(figure):
    return [text for ax in figure.axes for text in ax.get_legend_handles_labels()[1]]


def test_predictive_check_gives_the_size_of_a_misfit_beside_its_p_value():
    """Residuals twice the modelled noise: p near 0 and a residual scale near 2; residuals
    at the modelled noise: no flag (p ≥ 0.01) and a scale near 1."""
    rng = np.random.default_rng(4)
    samples, bins, sigma = 400, 300, 2.0
    mean = np.tile(50.0 * np.exp(-0.5 * ((np.arange(bins) - 150) / 20.0) ** 2), (samples, 1))
    variance = np.full((samples, bins), sigma**2)
    replicated = mean + sigma * rng.standard_normal((samples, bins))
    log_likelihood = rng.normal(-300.0, 3.0, samples)
    for factor, p_range in ((2.0, (0.0, 0.01)), (1.0, (0.01, 1.01))):
        observed = mean[0] + factor * sigma * rng.standard_normal(bins)
        fit = fit_statistics(log_likelihood, observed, replicated, mean, variance)
        assert p_range[0] <= fit["predictive_p_value"] < p_range[1]
        assert abs(fit["residual_scale"] - factor) < 0.1 * factor


def test_predictive_figure_marks_and_explains_floor_saturation_and_truth():
    result = tiny_result(seed=1)
    saturated = np.zeros(result.axis.size, bool)
    saturated[10:12] = True
    censored = np.zeros(result.axis.size, bool)
    censored[:3] = True
    result = replace(
        result,
        replicated=result.predictive + np.array([-3, -1, 0, 1, 3])[:, None],
        saturated=saturated,
        censored=censored,
        saturation=float(result.observed.max()),
        truth={"ground_elevation": 0.0},
        settings={"n_sigma": 4.0},
    )
    figure = predictive_plot(result)
    labels = "\n".join(_texts(figure))
    assert "observations: 90 % interval (5–95 %)" in labels  # with the noise
    assert "model mean b + a·W: 90 % interval (5–95 %)" in labels  # beside it, without
    assert "of samples inside" in labels
    assert "product's floor" in labels and "censored" in labels
    assert "digitiser maximum" in labels
    assert "front floor: noise mean + 6 σ of the smoothed noise" in labels
    assert "true ground" in labels
    assert len(figure.axes) == 2 and "observed − median model (DN)" in figure.axes[1].get_xlabel()


def test_corner_titles_state_their_quantiles_and_do_not_overlap():
    import matplotlib

    matplotlib.use("Agg")
    result = replace(tiny_result(seed=2), truth={"cover": 0.5, "top_height": 21.0})
    figure = corner_plot(result, names=["cover", "top_height", "gain"])
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    titles = [ax.title for ax in figure.axes if ax.get_title()]
    assert len(titles) == 3
    assert all("[" in t.get_text() and "]" in t.get_text() for t in titles)
    boxes = [t.get_window_extent(renderer) for t in titles]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not a.overlaps(b)
    note = "\n".join(t.get_text() for t in figure.texts)
    assert "median [5 %, 95 %]" in note and "orange lines: the true values" in note
    assert "upper limit of the stand's height" in note  # why the top-height truth sits high
    labels = [ax.get_xlabel() for ax in figure.axes if ax.get_xlabel()]
    assert "top height (m)" in labels and "gain (DN)" in labels


def test_corner_marks_a_parameter_the_waveform_left_at_its_prior():
    import matplotlib

    matplotlib.use("Agg")
    result = tiny_result(seed=3)
    result.diagnostics["prior_learning"] = {
        "cover": {"ks_distance": 0.02, "contraction": 0.01, "prior_dominated": True},
        "top_height": {"ks_distance": 0.8, "contraction": 0.9, "prior_dominated": False},
    }
    figure = corner_plot(result, names=["cover", "top_height"])
    titles = {ax.get_title().split("\n")[0]: ax.title for ax in figure.axes if ax.get_title()}
    assert set(titles) == {"crown cover (≈ prior)", "top height"}
    assert titles["crown cover (≈ prior)"].get_color() != titles["top height"].get_color()
    note = "\n".join(t.get_text() for t in figure.texts)
    assert "stayed at their prior" in note
    plain = corner_plot(tiny_result(seed=3), names=["cover", "top_height"])
    assert "stayed at their prior" not in "\n".join(t.get_text() for t in plain.texts)


def test_units_are_written_one_way():
    assert unit_label("m2/m2") == "m² m⁻²"
    assert unit_label("m3/m2/m") == "m³ m⁻² m⁻¹"
    assert unit_label("stems/ha") == "stems ha⁻¹"
    assert unit_label("1") == ""
