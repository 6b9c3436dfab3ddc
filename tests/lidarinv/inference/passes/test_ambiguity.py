"""Competing grounds: optima that explain a shot with the ground at another return."""

import numpy as np
import pytest

from forward.pulse import GaussianPulse, MeasuredPulse
from lidarinv.inference.model.parameters import default_space
from lidarinv.inference.passes.ambiguity import (
    MASS_WINDOW,
    competing_grounds,
    describe,
    pulse_width_m,
)
from lidarinv.inference.sampling.start import MapEstimate, laplace_covariance


def _two_basins(space, weight):
    """A log-density of two equal-width Gaussian basins in u, the second ``weight`` times
    the first's mass, with the ground 0.8 m apart (the ground prior spans ±1 m)."""
    column = space.names.index("ground_elevation")
    u = space.to_unbounded(space.sample_prior(np.random.default_rng(2), 1))[0]
    x = space.from_unbounded(np.where(np.isfinite(u), u, 0.0)[None])[0].repeat(2, axis=0)
    x[:, column] = [-0.4, 0.4]
    centres = space.to_unbounded(x)

    def log_prob(u):
        u = np.atleast_2d(u)
        d = [np.sum((u - c) ** 2, axis=1) / (2 * 0.01**2) for c in centres]
        return np.logaddexp(-d[0], np.log(weight) - d[1])

    optima = [(c, float(log_prob(c[None])[0])) for c in centres]
    best = MapEstimate(centres[0], optima[0][1], True, 0, laplace_covariance(log_prob, centres[0]))
    best.optima = optima
    return log_prob, best


@pytest.mark.parametrize("weight, expected", [(0.5, 2), (np.exp(-MASS_WINDOW) / 3, 1)])
def test_competing_ground_kept_only_with_a_comparable_mass(nuisance_priors, weight, expected):
    space = default_space(nuisance_priors)
    log_prob, estimate = _two_basins(space, weight)
    kept = competing_grounds(log_prob, estimate, space, separation_m=0.5)
    assert len(kept) == expected
    assert kept[0][1] == pytest.approx(-0.4, abs=1e-9)
    if expected == 2:
        assert kept[1][1] == pytest.approx(0.4, abs=1e-9)
        assert "ground ambiguous" in describe(kept) and "0.40 m" in describe(kept)
    else:
        assert describe(kept) is None


def test_grounds_within_a_pulse_width_are_one_explanation(nuisance_priors):
    space = default_space(nuisance_priors)
    log_prob, estimate = _two_basins(space, 1.0)
    assert len(competing_grounds(log_prob, estimate, space, separation_m=1.0)) == 1
    # a 4 ns (0.6 m) Gaussian pulse: its central 80 % spans 2.56 σ
    assert pulse_width_m(GaussianPulse(4.0)) == pytest.approx(
        2.563 * GaussianPulse(4.0).sigma_m, rel=1e-3
    )


def test_a_measured_pulse_is_as_wide_as_its_central_area_not_its_record():
    # a Gaussian of 4 ns FWHM sampled every 0.25 ns over a 64 ns record (9.6 m of offsets)
    times = np.arange(-32.0, 32.0, 0.25)
    sigma_ns = 4.0 / (2.0 * np.sqrt(2.0 * np.log(2.0)))
    measured = MeasuredPulse(np.exp(-0.5 * (times / sigma_ns) ** 2), 0.25)
    assert pulse_width_m(measured) == pytest.approx(pulse_width_m(GaussianPulse(4.0)), rel=2e-3)
    low, high = measured.support(0.1)
    assert high - low > 5.0 * pulse_width_m(measured)
