"""The stand parameter object and its height-distribution registry."""

import dataclasses

import numpy as np
import pytest

from forward.stand_params import HEIGHT_DISTRIBUTIONS, StandParams, height_distribution


@pytest.mark.parametrize("family", ["weibull", "lognormal"])
@pytest.mark.parametrize("mean, sd", [(15.0, 3.0), (6.0, 0.5), (22.0, 9.0)])
def test_families_reproduce_their_mean_and_sd(family, mean, sd):
    dist = height_distribution(family, mean, sd)
    assert dist.mean() == pytest.approx(mean, rel=1e-6)
    assert dist.std() == pytest.approx(sd, rel=1e-3)
    assert dist.ppf(0.0) >= 0.0  # heights are never negative


def test_truncated_normal_is_bounded():
    dist = height_distribution("truncnorm", 13.5, 0.75, truncation=2.0)
    assert dist.ppf(0.0) == pytest.approx(12.0)
    assert dist.ppf(1.0) == pytest.approx(15.0)
    # a parent normal that would reach below the ground is cut at zero
    low = height_distribution("truncnorm", 2.0, 2.0, truncation=3.0)
    assert low.ppf(0.0) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("family", sorted(HEIGHT_DISTRIBUTIONS))
@pytest.mark.parametrize("mean, sd", [(14.0, 3.0), (2.0, 1.5), (25.0, 0.4)])
def test_closed_forms_agree_with_scipy_stats(family, mean, sd):
    fam = HEIGHT_DISTRIBUTIONS[family]
    frozen = fam.frozen(mean, sd, 2.5)
    x = np.linspace(0.1, 40.0, 97)
    np.testing.assert_allclose(fam.pdf(x, mean, sd, 2.5), frozen.pdf(x), rtol=1e-9, atol=1e-300)
    q = np.array([1e-9, 1e-6, 0.1, 0.5, 0.9])
    np.testing.assert_allclose(fam.ppf(q, mean, sd, 2.5), frozen.ppf(q), rtol=1e-7)
    np.testing.assert_allclose(fam.isf(q, mean, sd, 2.5), frozen.isf(q), rtol=1e-7)
    np.testing.assert_allclose(fam.sf(x, mean, sd, 2.5), frozen.sf(x), rtol=1e-9, atol=1e-15)
    # partial mean ∫ₓ h f(h) dh against scipy's numerical expectation
    cuts = np.array([0.0, *fam.isf(np.array([0.5, 0.01]), mean, sd, 2.5)])
    reference = [frozen.expect(lambda h: h, lb=max(c, frozen.ppf(0.0))) for c in cuts]
    np.testing.assert_allclose(fam.mean_above(cuts, mean, sd, 2.5), reference, rtol=1e-7)
    # raw moments E[h^k], the closed forms behind the stand mapping's crown area and volume
    moments = fam.raw_moments((1, 2, 3), np.array([mean, mean]), np.array([sd, sd]), 2.5)
    assert moments.shape == (2, 3)
    expected = [frozen.moment(k) for k in (1, 2, 3)]
    np.testing.assert_allclose(moments, [expected, expected], rtol=1e-9)


def test_shape_mix_accepts_names_and_mappings():
    p = StandParams(
        density=500, height_mean=15, height_sd=3, shape_mix={"cone": 0.25, "ellipsoid": 0.75}
    )
    assert p.shape_mix == (0.25, 0.75, 0.0, 0.0)
    assert p.cohort2_shape_mix == p.shape_mix
    q = StandParams(
        density=500,
        height_mean=15,
        height_sd=3,
        shape_mix="cylinder",
        favd=0.5,
        favd_ratio={"cylinder": 2.0},
    )
    assert q.shape_mix == (0.0, 0.0, 0.0, 1.0)
    np.testing.assert_allclose(q.favd_by_shape(), [0.5, 0.5, 0.5, 1.0])
    assert q.crown_radius(10.0) == pytest.approx(1.0)
    assert q.crown_length(10.0) == pytest.approx(5.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        q.density = 3.0


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"density": -1.0}, "density"),
        ({"height_sd": 0.0}, "height_sd"),
        ({"height_family": "gamma"}, "height_family"),
        ({"shape_mix": {"cone": 0.5}}, "sum to 1"),
        ({"shape_mix": {"sphere": 1.0}}, "unknown crown shape"),
        ({"crown_length_ratio": 1.2}, "crown_length_ratio"),
        ({"favd": 0.0}, "favd"),
        ({"cohort2_fraction": 1.5}, "cohort2_fraction"),
        ({"cohort2_fraction": 0.5, "cohort2_height_sd": -1.0}, "cohort2_height_sd"),
        ({"height_sd": 100.0}, "outside what the weibull family supports"),
        ({"canopy_reflectance": np.nan}, "canopy_reflectance"),
    ],
)
def test_invalid_parameters_raise_clear_errors(changes, message):
    base = dict(density=500.0, height_mean=15.0, height_sd=3.0)
    base.update(changes)
    with pytest.raises(ValueError, match=message):
        StandParams(**base)
