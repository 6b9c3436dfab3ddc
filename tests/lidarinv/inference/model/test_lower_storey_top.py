"""The lower storey's top coordinate: exact inverse and Jacobian, the lower storey's top
held in place, the prior and the posterior unchanged, the compiled map equal to numpy."""

from dataclasses import replace

import numpy as np
import pytest
from jacobian_check import assert_exact_jacobian, assert_log_derivative, assert_same_posterior

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings
from lidarinv.inference.model import coordinates
from lidarinv.inference.model.parameters import default_space
from lidarinv.inference.model.priors import Uniform
from lidarinv.inference.problem import problem_for_shot
from lidarinv.inference.shot import Shot

BOUNDS = (0.1, 0.9)
WITH = (*coordinates.DEFAULT_RIDGES, "lower-storey-top")
WITHOUT = coordinates.DEFAULT_RIDGES


@pytest.mark.parametrize("power", [1.0, coordinates.LOWER_TOP_WALL_POWER])
def test_round_trip_with_exact_jacobian(power):
    rng = np.random.default_rng(21)
    ratio = rng.uniform(0.1001, 0.8999, 300)
    top = rng.uniform(2.0, 60.0, 300)
    c = coordinates.lower_top_from_ratio(ratio, top, BOUNDS, power)
    back, log_jac = coordinates.ratio_from_lower_top(c, top, BOUNDS, power)
    np.testing.assert_allclose(back, ratio, rtol=1e-11)
    assert_log_derivative(
        lambda v: coordinates.ratio_from_lower_top(v, top, BOUNDS, power)[0], c, log_jac
    )
    bad = coordinates.lower_top_from_ratio(np.array([0.5, 0.9, 0.1]), [-1.0, 20.0, 20.0], BOUNDS)
    assert np.all(np.isnan(bad))
    assert np.all(np.isnan(coordinates.ratio_from_lower_top(np.zeros(2), [0.0, -3.0], BOUNDS)[0]))


def test_power_one_is_the_logistic_form_of_the_crown_base():
    """p = 1: c = logit(t) + ln((ρ₁ − ρ₀)·H₁), t the prior-unit position of ρ."""
    ratio, top = np.array([0.15, 0.5, 0.85]), np.array([10.0, 25.0, 50.0])
    t = (ratio - 0.1) / 0.8
    expected = np.log(t / (1 - t)) + np.log(0.8 * top)
    got = coordinates.lower_top_from_ratio(ratio, top, BOUNDS, power=1.0)
    np.testing.assert_allclose(got, expected, rtol=1e-12)


@pytest.mark.parametrize("power", [1.0, coordinates.LOWER_TOP_WALL_POWER])
def test_the_lower_storeys_top_stays_in_place_as_the_upper_top_moves(power):
    """At fixed c, ∂H₂/∂H₁ = ρ₀ + (ρ₁ − ρ₀)·t^{p+1} (against ρ at fixed ρ): away from the
    upper wall the lower storey's top hardly moves; with a plain log, c = ln(H₂ − ρ₀H₁)."""
    ratio = np.array([0.2, 0.4, 0.6, 0.75])
    top = np.full(4, 30.0)
    c = coordinates.lower_top_from_ratio(ratio, top, BOUNDS, power)
    h = 1e-4
    lower_top = [
        coordinates.ratio_from_lower_top(c, top + d, BOUNDS, power)[0] * (top + d) for d in (h, -h)
    ]
    slope = (lower_top[0] - lower_top[1]) / (2 * h)
    t = (ratio - 0.1) / 0.8
    np.testing.assert_allclose(slope, 0.1 + 0.8 * t ** (power + 1), rtol=1e-6)
    assert np.all(slope < ratio)
    small = coordinates.lower_top_from_ratio(0.1 + 1e-4, 30.0, BOUNDS, power)
    assert small == pytest.approx(np.log(1e-4 * 30.0), abs=2e-4)  # t^p/p off the plain log


@pytest.mark.parametrize("power", [1.0, coordinates.LOWER_TOP_WALL_POWER])
def test_the_coordinate_spans_the_prior_and_keeps_it(power):
    """Every c maps inside [ρ₀, ρ₁] with a finite Jacobian; ρ's uniform prior carried to c
    integrates to one at every upper top."""
    c = np.linspace(-60.0, 60.0, 2001)
    ratio, log_jac = coordinates.ratio_from_lower_top(c, 20.0, BOUNDS, power)
    assert np.all((ratio >= BOUNDS[0]) & (ratio <= BOUNDS[1])) and np.all(np.isfinite(log_jac))
    assert ratio[0] == pytest.approx(BOUNDS[0]) and ratio[-1] == pytest.approx(BOUNDS[1])
    prior = Uniform(*BOUNDS)
    for top in (1.5, 20.0, 70.0):
        c = np.linspace(np.log(top) - 40.0, np.log(top) + 40.0 / power, 400_001)
        ratio, log_jac = coordinates.ratio_from_lower_top(c, top, BOUNDS, power)
        density = np.exp(prior.log_pdf(ratio) + log_jac)
        assert np.trapezoid(density, c) == pytest.approx(1.0, abs=1e-5)


def _two_storey_space(nuisance_priors, ridges=WITH, **kwargs):
    return default_space(nuisance_priors, cohorts=2, ridges=ridges, **kwargs)


def _prior_rows(space, seed, n):
    x = space.sample_prior(np.random.default_rng(seed), 10 * n)
    u = space.to_unbounded(x)
    finite = np.isfinite(u).all(axis=1)
    return x[finite][:n], u[finite][:n]


@pytest.mark.parametrize("tallest_stem", [False, True])
def test_space_samples_the_lower_storeys_top_with_exact_jacobian(nuisance_priors, tallest_stem):
    space = _two_storey_space(nuisance_priors, tallest_stem=tallest_stem)
    assert "lower-storey-top" in space.signature()
    k, top = space.names.index("cohort2_top_ratio"), space.names.index("top_height")
    x, u = _prior_rows(space, 22, 20)
    expected = coordinates.lower_top_from_ratio(
        x[:, k], x[:, top], BOUNDS, coordinates.LOWER_TOP_WALL_POWER
    )
    np.testing.assert_allclose(u[:, k], expected, rtol=1e-12)
    back, log_jac = space.from_unbounded(u)
    np.testing.assert_allclose(back, x, rtol=1e-10, atol=1e-12)
    assert_exact_jacobian(space, u[:4], log_jac[:4])
    # the prior density in u: the other coordinates' the same, ρ's carried by ∂ρ/∂c
    plain = _two_storey_space(nuisance_priors, ridges=WITHOUT, tallest_stem=tallest_stem)
    _, plain_jac = plain.from_unbounded(plain.to_unbounded(x))
    ratio_prior = space.by_name["cohort2_top_ratio"].prior
    _, ratio_jac = coordinates.ratio_from_lower_top(u[:, k], x[:, top], BOUNDS)
    _, ratio_plain_jac = ratio_prior.from_unbounded(ratio_prior.to_unbounded(x[:, k]))
    np.testing.assert_allclose(log_jac - ratio_jac, plain_jac - ratio_plain_jac, atol=1e-9)


def test_the_coordinate_needs_a_free_ratio_and_a_top(nuisance_priors):
    assert "lower-storey-top" not in _two_storey_space(nuisance_priors, WITHOUT).signature()
    assert "lower-storey-top" not in default_space(nuisance_priors, ridges=WITH).signature()
    fixed = _two_storey_space(nuisance_priors).with_changes({"cohort2_top_ratio": {"fixed": 0.5}})
    assert "lower-storey-top" not in fixed.signature()
    fixed_top = _two_storey_space(nuisance_priors).with_changes({"top_height": {"fixed": 25.0}})
    k = fixed_top.names.index("cohort2_top_ratio")
    x, u = _prior_rows(fixed_top, 23, 10)
    np.testing.assert_allclose(u[:, k], coordinates.lower_top_from_ratio(x[:, k], 25.0, BOUNDS))
    np.testing.assert_allclose(fixed_top.from_unbounded(u)[0], x, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize(
    "changes",
    [{}, {"top_height": {"fixed": 22.0}}, {"cohort2_top_ratio": {"prior": Uniform(0.0, 1.0)}}],
)
def test_compiled_lower_storey_map_equals_the_numpy_reference(changes, nuisance_priors):
    """Values, Jacobians and NaNs, near the prior and far beyond it."""
    space = _two_storey_space(nuisance_priors).with_changes(changes)
    rng = np.random.default_rng(24)
    u = space.to_unbounded(space.sample_prior(rng, 2000))
    u = np.where(np.isfinite(u), u, 0.0)
    u[700:] += rng.normal(0.0, 4.0, u[700:].shape)
    k = space.names.index("cohort2_top_ratio")
    u[::89, k] = np.nan
    u[1:5, k] = [-800.0, 800.0, 1e6, -1e6]  # e^{pz} over- and underflowing
    compiled, jac = space.from_unbounded(u, backend="numba")
    with np.errstate(all="ignore"):
        reference, jac_reference = space.from_unbounded(u, backend="numpy")
    np.testing.assert_allclose(compiled, reference, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(jac, jac_reference, rtol=1e-12, atol=1e-10)
    assert np.isnan(compiled[::89, k]).all() and np.isfinite(compiled[700:, k]).mean() > 0.9


def test_the_posterior_is_the_same_at_matched_stands(rng):
    """The log-posterior in either coordinate set at the same physical stand differs by the
    log-Jacobians alone; the expected waveform's quantities (the blobs) are the same."""
    settings = InversionSettings(discrepancy_model="observed", cohorts=2)
    shot = Shot.from_observation(synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], rng), settings)
    problems = [problem_for_shot(shot, replace(settings, ridges=r)) for r in (WITH, WITHOUT)]
    assert "lower-storey-top" in problems[0].space.signature()
    assert problems[0].space.names == problems[1].space.names
    assert_same_posterior(problems, problems[1].space.sample_prior(rng, 64))
