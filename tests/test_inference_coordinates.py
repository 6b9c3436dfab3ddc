"""The crown-base sampling coordinate: exact inverse, exact Jacobian, prior unchanged."""

import numpy as np
import pytest

from lidarinv.inference import coordinates
from lidarinv.inference.parameters import default_space


def test_crown_base_coordinate_round_trip_with_exact_jacobian():
    rng = np.random.default_rng(3)
    ratio = rng.uniform(0.1, 0.999, 300)
    mean = rng.uniform(0.5, 40.0, 300)
    b = coordinates.crown_base_from_ratio(ratio, mean)
    np.testing.assert_allclose(np.exp(b), (1.0 - ratio) * mean, rtol=1e-12)
    back, log_jac = coordinates.ratio_from_crown_base(b, mean)
    np.testing.assert_allclose(back, ratio, rtol=1e-12)
    h = 1e-6
    slope = (
        coordinates.ratio_from_crown_base(b + h, mean)[0]
        - coordinates.ratio_from_crown_base(b - h, mean)[0]
    ) / (2 * h)
    np.testing.assert_allclose(log_jac, np.log(np.abs(slope)), atol=1e-6)
    # no stand (mean height ≤ 0) or no crown base (ℓ = 1): no coordinate
    assert np.all(np.isnan(coordinates.crown_base_from_ratio(np.array([0.5, 1.0]), [-1.0, 9.0])))
    assert np.all(np.isnan(coordinates.ratio_from_crown_base(np.zeros(2), [0.0, -3.0])[0]))


@pytest.mark.parametrize("mean_height", [1.5, 15.0, 60.0])
def test_crown_base_coordinate_keeps_the_ratio_prior(mean_height, nuisance_priors):
    """The ratio's prior carried to b = ln B with the Jacobian integrates to one."""
    prior = default_space(nuisance_priors).by_name["crown_length_ratio"].prior
    b = np.linspace(np.log(mean_height) - 40.0, np.log(mean_height) + 1.0, 400_001)
    ratio, log_jac = coordinates.ratio_from_crown_base(b, mean_height)
    with np.errstate(invalid="ignore"):
        density = np.exp(prior.log_pdf(ratio) + log_jac)
    assert np.trapezoid(density, b) == pytest.approx(1.0, abs=1e-4)


BOTH = ("cover-pai", "crown-base")


def test_space_samples_the_crown_base_of_the_mean_tree(nuisance_priors):
    space = default_space(nuisance_priors, ridges=BOTH)
    assert "crown-base" in space.signature()
    r, top, sd = (space.names.index(k) for k in ("crown_length_ratio", "top_height", "height_sd"))
    x = space.sample_prior(np.random.default_rng(5), 400)
    x = x[x[:, top] > 2.0 * x[:, sd]][:50]
    u = space.to_unbounded(x)
    base = (1.0 - x[:, r]) * (x[:, top] - 2.0 * x[:, sd])
    np.testing.assert_allclose(u[:, r], np.log(base), rtol=1e-12)
    back, _ = space.from_unbounded(u)
    np.testing.assert_allclose(back, x, rtol=1e-10)
    # a move to a height distribution with no mean height is outside the prior
    u_bad = u[:1].copy()
    u_bad[0, sd], u_bad[0, top] = 30.0, -30.0  # sd 10 m, top 1 m: mean height < 0
    x_bad, _ = space.from_unbounded(u_bad)
    assert space.log_prior(x_bad)[0] == -np.inf


def test_crown_base_uses_a_fixed_height_and_can_be_turned_off(nuisance_priors):
    fixed_top = default_space(nuisance_priors, ridges=BOTH)
    fixed_top = fixed_top.with_changes({"top_height": {"fixed": 25.0}})
    r, sd = fixed_top.names.index("crown_length_ratio"), fixed_top.names.index("height_sd")
    x = fixed_top.sample_prior(np.random.default_rng(6), 20)
    x[:, sd] = np.minimum(x[:, sd], 10.0)
    u = fixed_top.to_unbounded(x)
    np.testing.assert_allclose(np.exp(u[:, r]), (1.0 - x[:, r]) * (25.0 - 2.0 * x[:, sd]))
    per_parameter = default_space(nuisance_priors)  # crown-base is opt-in
    assert "crown-base" not in per_parameter.signature()
    r = per_parameter.names.index("crown_length_ratio")
    x = per_parameter.sample_prior(np.random.default_rng(7), 5)
    prior = per_parameter.by_name["crown_length_ratio"].prior
    np.testing.assert_allclose(per_parameter.to_unbounded(x)[:, r], prior.to_unbounded(x[:, r]))
    fixed_ratio = default_space(nuisance_priors, ridges=BOTH)
    fixed_ratio = fixed_ratio.with_changes({"crown_length_ratio": {"fixed": 0.4}})
    assert "crown-base" not in fixed_ratio.signature()
    with pytest.raises(ValueError, match="unknown sampling coordinates"):
        default_space(nuisance_priors, ridges=("crown-tip",))
