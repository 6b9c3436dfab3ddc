"""The expected waveform of a stand conditioned on its tallest tree: cohort 1 stopped at
``height_cap`` and apex trees at the cap (``apex_density``)."""

import numpy as np
import pytest

import forward as fw
from forward.examples import example_stand
from forward.expected import CONVERGED, DEFAULT_FREE, ExpectedWaveformModel, ModelSettings
from forward.expected.vectors import FIELD_INDEX, params_from_vector, physical_rows
from forward.realise import realise, scene_extras
from forward.stand import Stand
from forward.stand_params import HEIGHT_DISTRIBUTIONS

INSTRUMENT = fw.instrument_preset("gedi", footprint_sigma_m=2.5)
FREE = (*DEFAULT_FREE, "height_cap", "apex_density")
PARAMS = example_stand(height_family="truncnorm", shape_mix={"cone": 0.4, "ellipsoid": 0.6})
TOP = PARAMS.height_mean + 2.0 * PARAMS.height_sd  # the truncated normal's tallest tree


def _model(settings=None, params=PARAMS, heights=None):
    if heights is None:
        heights = fw.WaveformSimulator(INSTRUMENT).default_heights(30.0, -3.0)
    return ExpectedWaveformModel(INSTRUMENT, heights, params, FREE, settings)


def _rows(model, cap, apex):
    theta = np.repeat(model.vector(model.template)[None, :], np.size(cap), axis=0)
    theta[:, model.parameter_names.index("height_cap")] = cap
    theta[:, model.parameter_names.index("apex_density")] = apex
    return theta


def test_a_cap_above_the_tallest_tree_changes_nothing():
    model = _model()
    out = model(_rows(model, [np.inf, TOP + 0.5, TOP + 20.0], 0.0))
    np.testing.assert_allclose(out[1:], out[[0, 0]], rtol=1e-12, atol=1e-15)


def test_no_crown_above_the_cap_and_less_canopy_below_a_lower_one():
    model = _model()
    caps = np.array([np.inf, 19.0, 16.0, 12.0])
    theta = _rows(model, caps, 0.0)
    z = np.array([0.0, 11.0, 12.0, 16.0, 19.0, 20.0])
    gap = model.gap(theta, z)
    for row, cap in enumerate(caps[1:], start=1):
        assert np.all(gap[row, z >= cap] == 1.0)
        assert np.all(gap[row, z < cap] < 1.0)
    assert np.all(np.diff(gap[:, 0]) > 0)  # fewer trees, more light on the ground
    out = model.evaluate(theta)
    assert np.all(np.diff(out.canopy.sum(axis=1)) < 0)


def test_apex_trees_alone_equal_a_cohort_of_that_height():
    """No stems but apex trees at 18 m: the stand of that density whose heights all lie
    within 0.4 mm below 18 m (a normal of sd 0.1 mm truncated at ±2 sd), both on the
    converged per-edge path (the fast grid follows each template's tallest tree)."""
    model = _model(CONVERGED)
    theta = _rows(model, 18.0, 150.0)
    theta[0, model.parameter_names.index("density")] = 0.0
    narrow = PARAMS.with_values(density=150.0, height_mean=17.9998, height_sd=1e-4)
    reference = _model(CONVERGED, params=narrow)
    expected = reference(reference.vector(narrow)[None, :])
    np.testing.assert_allclose(model(theta), expected, rtol=0, atol=1e-5 * expected.max())


def test_numba_and_numpy_backends_agree_on_conditioned_stands():
    pytest.importorskip("numba")
    out = {}
    for backend in ("numpy", "numba"):
        model = _model(ModelSettings(backend=backend))
        theta = _rows(model, [np.inf, 19.0, 14.0, 16.5], [0.0, 30.0, 0.0, 80.0])
        out[backend] = model(theta), model.gap(theta, [0.0, 5.0, 12.0, 18.0])
    for numpy_result, numba_result in zip(out["numpy"], out["numba"]):
        np.testing.assert_allclose(numba_result, numpy_result, rtol=1e-10, atol=1e-14)


def test_mean_of_conditioned_explicit_stands_matches_the_model():
    """Explicit stands whose trees above the cap are removed and to which Poisson apex
    trees at the cap are added: their mean waveform is the conditioned expectation."""
    cap, apex = 17.0, 60.0
    params = PARAMS.with_values(density=500.0)
    sim = fw.WaveformSimulator(INSTRUMENT, fw.AccuracySettings(radial_nodes=6, angular_nodes=12))
    heights = sim.default_heights(32.0, 0.0)
    model = _model(ModelSettings(height_nodes=96, radial_nodes=12), params, heights)
    expected = model(_rows(model, cap, apex))[0]
    ground, understory, rho_v = scene_extras(params)
    rng = np.random.default_rng(20003)
    side = 2 * (sim.footprint_radius + 6.0)
    mix = np.array(params.shape_mix)
    runs = []
    for _ in range(300):
        trees = realise(params, side, rng, origin=(-side / 2, -side / 2))
        keep = trees.height <= cap
        k = rng.poisson(apex * 1e-4 * side**2)
        height = np.concatenate([trees.height[keep], np.full(k, cap)])
        shape = np.concatenate([trees.shape[keep], rng.choice(mix.size, size=k, p=mix)])
        stand = Stand(
            x=np.concatenate([trees.x[keep], rng.uniform(-side / 2, side / 2, k)]),
            y=np.concatenate([trees.y[keep], rng.uniform(-side / 2, side / 2, k)]),
            height=height,
            crown_length=params.crown_length(height),
            crown_radius=params.crown_radius(height),
            shape=shape.astype(np.int8),
            favd=params.favd_by_shape()[shape],
        )
        runs.append(sim.simulate(stand, (0.0, 0.0), heights, ground, rho_v, understory).samples)
    runs = np.array(runs)
    n = runs.shape[0]
    mean, se = runs.mean(0), runs.std(0, ddof=1) / np.sqrt(n)
    usable = se > 0.05 * se.max()
    z = (mean - expected)[usable] / se[usable]
    assert np.max(np.abs(z)) < 4.5, np.round(z, 2)
    above = heights > cap + 6 * INSTRUMENT.pulse.sigma_m  # beyond the pulse's reach
    assert np.all(expected[above] < 1e-7 * expected.max())
    total_z = (runs.sum(1).mean() - expected.sum()) / (runs.sum(1).std(ddof=1) / np.sqrt(n))
    assert abs(total_z) < 4.0


def test_invalid_conditioning_is_masked_and_has_no_stem_map():
    model = _model()
    theta = _rows(model, [np.nan, np.inf, 15.0, -1.0, 15.0], [0.0, 10.0, -5.0, 0.0, 10.0])
    assert model.valid(theta).tolist() == [False, False, False, False, True]
    full = model.full_vectors(theta)
    family = HEIGHT_DISTRIBUTIONS["truncnorm"]
    assert physical_rows(full, family, 2.0).tolist() == [False, False, False, False, True]
    params, _ = params_from_vector(model.full_vectors(_rows(model, np.inf, 0.0))[0], PARAMS)
    assert params == PARAMS
    with pytest.raises(ValueError, match="height_cap"):
        params_from_vector(full[4], PARAMS)
    assert FIELD_INDEX["height_cap"] < FIELD_INDEX["mix_cone"]


@pytest.mark.parametrize("family", ["truncnorm", "lognormal"])
def test_a_cohort_cut_to_some_rows_is_the_cohort_of_those_rows(family):
    """The model sends rows to exact depths or to the grid by their narrowest cohort and
    cuts the cohorts it has to those rows: exactly what computing them again gives, for
    two storeys, a cap and apex trees, and a family whose location is a scalar."""
    params = example_stand(
        height_family=family, shape_mix={"cone": 0.4, "ellipsoid": 0.6},
        cohort2_fraction=0.5, cohort2_height_mean=6.0, cohort2_height_sd=1.5,
        cohort2_shape_mix="cone",
    )  # fmt: skip
    model = _model(params=params)
    rows = _rows(model, cap=np.linspace(TOP - 3.0, TOP + 5.0, 7), apex=[0.0, 20.0] * 3 + [5.0])
    full = model._full(rows)
    keep = np.array([True, False, True, True, False, False, True])
    whole, cut = model._cohorts(full), model._cohorts(full[keep])
    assert len(whole) == len(cut) == 3  # both storeys and the apex trees
    heights = np.linspace(0.0, 2.0 * TOP, 40)[None, :]
    for mine, theirs in zip(model._rows(whole, keep), cut, strict=True):
        for name in ("stems", "lo", "hi", "fractions", "present"):
            np.testing.assert_array_equal(getattr(mine, name), getattr(theirs, name))
        if theirs.pdf is not None:
            grid = np.repeat(heights, keep.sum(), axis=0)
            np.testing.assert_array_equal(mine.pdf(grid), theirs.pdf(grid))
