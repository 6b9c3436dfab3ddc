"""The model-discrepancy variance, and the Poisson-stand spread behind it, against explicit
random stands."""

import numpy as np
import pytest
from scipy import stats

from forward import derived, poisson_stand
from forward.expected import ExpectedWaveformModel
from forward.explicit import WaveformSimulator
from forward.instrument import instrument_preset
from forward.realise import realise, scene_extras
from lidarinv.examples import (
    SYNTHETIC_SHOTS,
    synthetic_shot,
    tallest_within,
    true_values,
)
from lidarinv.inference import InversionSettings, build_problem
from lidarinv.inference.likelihood.discrepancy import DISCREPANCY_MODELS, model_variance
from lidarinv.inference.model.stand import TOP_SDS, StandMapping, default_template

STAND = SYNTHETIC_SHOTS["gedi-mixed"].params


def _parameters(params):
    return {
        "top_height": np.array([params.height_mean + TOP_SDS * params.height_sd]),
        "height_sd": np.array([params.height_sd]),
        "crown_length_ratio": np.array([params.crown_length_ratio]),
        "density_m2": np.array([params.density * 1e-4]),
    }


def test_crowns_spanning_a_height_match_a_count_in_realised_stands(rng):
    mapping = StandMapping(default_template())
    z = np.array([0.0, 8.0, 12.0, 16.0, 19.0, 21.9, 23.0])
    expected = mapping.crowns_spanning(_parameters(STAND), z[None, :])[0]
    side = 400.0
    counts = np.zeros(z.size)
    for _ in range(4):
        stand = realise(STAND, side, rng)
        base = stand.height - stand.crown_length
        counts += np.sum((base[:, None] <= z) & (z <= stand.height[:, None]), axis=0)
    per_m2 = counts / (4 * side**2)
    se = np.sqrt(np.maximum(counts, 1.0)) / (4 * side**2)
    assert np.all(np.abs(per_m2 - expected) < 4 * se + 1e-12)
    assert expected[0] == 0.0 and expected[-1] == 0.0  # below every crown base, above all


def test_crown_count_model_follows_the_spread_of_explicit_realisations(rng):
    instrument = instrument_preset("gedi")
    heights = np.arange(-3.0, 26.0, instrument.bin_height)
    side = 3.0 * instrument.footprint_diameter_m
    simulator = WaveformSimulator(instrument)
    ground, understory, rho_v = scene_extras(STAND)
    canopy, ground_energy = [], []
    for _ in range(120):
        w = simulator.simulate(
            realise(STAND, side, rng), (side / 2, side / 2), heights, ground, rho_v, understory
        )
        canopy.append(w.canopy)
        ground_energy.append(np.sum(w.samples - w.canopy))
    canopy = np.array(canopy)
    area = instrument.footprint_effective_area_m2
    crowns = (
        area
        * StandMapping(default_template()).crowns_spanning(_parameters(STAND), heights[None, :])[0]
    )
    mean, var = canopy.mean(axis=0), canopy.var(axis=0)
    bulk = (mean > 0.05 * mean.max()) & (heights > STAND.understory_height + 1.0)
    ratio = var[bulk] * np.maximum(crowns[bulk], 1.0) / mean[bulk] ** 2
    assert 0.6 < np.median(ratio) < 1.7  # κ = 1 describes a Poisson stand
    # the ground return varies as the footprint's gap fraction
    model = ExpectedWaveformModel(instrument, heights, STAND)
    understory_gap = np.exp(-instrument.extinction_per_favd * STAND.understory_lai)
    gap = model.evaluate(model.vector(STAND)).gap_ground / understory_gap
    crown_area = poisson_stand.crown_count(derived.canopy_cover(STAND)) / (STAND.density * 1e-4)
    modelled = np.sqrt(poisson_stand.footprint_gap_cv2(gap, crown_area, area))[0]
    measured = np.std(ground_energy) / np.mean(ground_energy)
    assert measured == pytest.approx(modelled, rel=0.35)


def test_observed_discrepancy_follows_the_shot_and_not_the_parameters(rng):
    z = np.arange(-5.0, 40.0, 0.15)
    signal = 120.0 * np.exp(-0.5 * (z / 0.8) ** 2)
    samples = 50.0 + signal + rng.normal(0.0, 2.0, z.size)
    variance = DISCREPANCY_MODELS["observed"](samples, 50.0, 1.0, 0.2)
    peak = np.argmax(signal)
    assert variance[peak] == pytest.approx((0.2 * 120.0) ** 2, rel=0.1)
    assert np.all(variance[z > 10.0] < (0.2 * 4 * 2.0) ** 2)  # noise alone adds little
    np.testing.assert_allclose(
        model_variance(0.2, np.array([2.0, 3.0]), signal[None, :] * np.ones((2, 1))),
        (0.2 * np.array([[2.0], [3.0]]) * signal) ** 2,
    )
    # in the posterior: the same per-bin variance for every row, whatever its parameters
    shot = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], rng, shot_id=1)
    post = build_problem(shot, InversionSettings(discrepancy_model="observed")).log_posterior
    assert post.likelihood.fixed_discrepancy.shape == post.data.axis.shape
    with pytest.raises(ValueError, match="unknown discrepancy model"):
        build_problem(shot, InversionSettings(discrepancy_model="kriging"))


def test_tallest_stem_in_a_footprint_matches_realised_stands(rng):
    """The predictive draw of a footprint's tallest stem follows the tallest stem within
    the footprint radius of explicit realisations (two-sample KS), and lies below the
    height distribution's upper end, which a footprint's few stems rarely reach."""
    mapping = StandMapping(default_template())
    radius = 12.5
    realised = []
    for _ in range(300):
        stand = realise(STAND, 40.0, rng)
        realised.append(tallest_within(stand, (20.0, 20.0), radius / 2.0))
    values = {k: np.repeat(v, 3000) for k, v in _parameters(STAND).items()}
    drawn = mapping.tallest_in_area(values, np.pi * radius**2, rng.uniform(size=3000))
    assert stats.ks_2samp(realised, drawn).pvalue > 1e-3
    expected = derived.expected_max_height(STAND, 2.0 * radius)  # ∫(1 − e^(−λA·S)) dh
    assert abs(np.mean(drawn) - expected) < 4.0 * np.std(drawn) / np.sqrt(drawn.size)
    top = STAND.height_mean + TOP_SDS * STAND.height_sd
    assert np.all(drawn <= top) and np.median(drawn) < top - 0.2 * STAND.height_sd
    # no stem at all: a stand too sparse to hold one in the area gives the ground
    sparse = {**values, "density_m2": np.full(3000, 1e-6)}
    assert np.mean(mapping.tallest_in_area(sparse, 1.0, rng.uniform(size=3000)) == 0) > 0.99


def test_synthetic_shot_knows_its_footprint_top(rng):
    recipe = SYNTHETIC_SHOTS["gedi-mixed"]
    explicit = synthetic_shot(recipe, rng)
    assert 0 < explicit.truth["footprint_top_height"] <= explicit.truth["top_height"]
    assert np.isnan(synthetic_shot(recipe, rng, explicit=False).truth["footprint_top_height"])


@pytest.mark.parametrize(
    "changes",
    [{}, {"density": 80.0}, {"height_mean": 3.0, "height_sd": 2.5, "favd": 0.3}],
    ids=["gedi-mixed", "sparse", "cut-at-the-ground"],
)
def test_stand_mapping_inverts_the_parameterisation_and_matches_forward_derived(changes):
    """A stand's inversion parameters map back to its density, heights and FAVD, and the
    mapping's closed-form derived quantities equal forward.derived's quadratures."""
    params = SYNTHETIC_SHOTS["gedi-mixed"].params.with_values(**changes)
    truth = true_values(params, 1.0, 0.0, 1.0)
    v = {name: np.array([value]) for name, value in truth.items()}
    v.update(crown_radius_slope=np.array([params.crown_radius_slope]), ground_elevation=np.zeros(1))
    mapping = StandMapping(default_template())
    vectors, found = mapping.model_vectors(v)
    column = dict(zip(mapping.model_free, vectors[0]))
    assert column["density"] == pytest.approx(params.density, rel=1e-6)
    assert column["height_mean"] == pytest.approx(params.height_mean, rel=1e-9)
    assert column["height_sd"] == pytest.approx(params.height_sd, rel=1e-9)
    assert column["favd"] == pytest.approx(params.favd, rel=1e-6)
    assert found["mean_height"][0] == pytest.approx(derived.mean_height(params), rel=1e-6)
    assert found["dominant_height"][0] == pytest.approx(derived.dominant_height(params), rel=1e-3)
    assert found["crown_volume"][0] == pytest.approx(derived.crown_volume_per_ha(params), rel=1e-6)
    assert found["lai"][0] == pytest.approx(derived.leaf_area_index(params), rel=1e-9)
