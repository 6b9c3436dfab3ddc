"""The recovery study's out-of-family truth stands (``studies/out_of_family_stands.py``):
each generator gives a valid stem map of the kind it names, and a shot carries the
footprint truths the posterior is compared with."""

import numpy as np
import out_of_family_stands  # studies/out_of_family_stands.py (pyproject's pythonpath)
import pytest
from scipy import stats

from forward.stand_params import height_distribution

SIGMA_F = 6.25  # GEDI's footprint σf (m)


@pytest.fixture
def ood():
    return out_of_family_stands


def scenes(ood, kind, n=4, seed=0):
    rng = np.random.default_rng(seed)
    return [ood.draw_scene(kind, rng) for _ in range(n)]


def pairs_within(stand, r, side):
    """Stem pairs closer than r (m), periodic distances on the square plot."""
    dx = np.abs(stand.x[:, None] - stand.x[None, :])
    dy = np.abs(stand.y[:, None] - stand.y[None, :])
    dx, dy = np.minimum(dx, side - dx), np.minimum(dy, side - dy)
    return (np.count_nonzero(dx**2 + dy**2 < r * r) - stand.n_trees) / 2


@pytest.mark.parametrize("kind", ["weibull", "lognormal", "two-storey", "emergent", "clumped",
                                  "sparse", "dense"])  # fmt: skip
def test_every_kind_gives_a_valid_stand_around_the_beam(ood, kind):
    for _, stand, centre in scenes(ood, kind):
        assert stand.n_trees > 0
        assert np.all(stand.height > 0) and np.all(stand.crown_length <= stand.height)
        near = np.hypot(stand.x - centre[0], stand.y - centre[1]) < 2 * SIGMA_F
        assert near.any() or kind == "sparse"


def test_single_cohort_heights_follow_their_skewed_family(ood):
    for kind in ("weibull", "lognormal"):
        for params, stand, _ in scenes(ood, kind, n=3, seed=1):
            dist = height_distribution(kind, params.height_mean, params.height_sd)
            assert stats.kstest(stand.height, dist.cdf).pvalue > 1e-3
    # lognormal heights have a long upper tail
    assert all(stats.skew(s.height) > 0 for _, s, _ in scenes(ood, "lognormal", n=3, seed=2))


def test_two_storeys_give_a_bimodal_height_histogram(ood):
    for params, stand, _ in scenes(ood, "two-storey", n=5, seed=3):
        upper, lower = params.height_mean, params.cohort2_height_mean
        middle = 0.5 * (upper + lower)
        band = [np.count_nonzero(np.abs(stand.height - h) < 1.0) for h in (lower, middle, upper)]
        assert band[1] < 0.5 * min(band[0], band[2])


def test_the_emergent_tree_is_the_footprints_tallest_and_stands_well_clear(ood):
    for _, stand, centre in scenes(ood, "emergent", n=5, seed=4):
        tallest = np.argmax(stand.height)
        assert np.hypot(stand.x[tallest] - centre[0], stand.y[tallest] - centre[1]) <= SIGMA_F
        others = np.delete(stand.height, tallest)
        assert stand.height[tallest] >= others.max() + 8.0


def test_clumped_stems_pair_up_at_short_range_more_than_poisson_stems(ood):
    side = 3 * 4 * SIGMA_F
    for _, stand, _ in scenes(ood, "clumped", n=4, seed=5):
        r = 2.0
        n = stand.n_trees
        poisson = 0.5 * n * (n - 1) * np.pi * r * r / side**2  # expected pairs, CSR
        assert pairs_within(stand, r, side) > 1.5 * poisson


def test_sparse_stands_cover_less_than_dense_ones(ood):
    def cover(kind, seed):
        return [
            ood.footprint_crown_cover(stand, centre, SIGMA_F)
            for _, stand, centre in scenes(ood, kind, n=4, seed=seed)
        ]

    sparse, dense = cover("sparse", 6), cover("dense", 7)
    assert max(sparse) < 0.5 < 0.7 < min(dense)
    for _, stand, _ in scenes(ood, "dense", n=2, seed=8):  # a hard-core pattern
        assert pairs_within(stand, 0.79, 3 * 4 * SIGMA_F) == 0


def test_a_shot_carries_the_footprint_truths(ood):
    obs = ood.out_of_family_shot(np.random.default_rng(9), index=3)  # the emergent kind
    truth = obs.truth
    assert truth["kind"] == "emergent" and truth["ground_elevation"] == 0.0
    # the emergent tree tops the footprint; RH98 lies below the tallest stem's top
    assert 0.0 < truth["rh98"] < truth["footprint_top_height"]
    assert 0.0 <= truth["gap_cover"] <= truth["cover"] <= 1.0
    assert np.isnan(truth.get("top_height", np.nan))
