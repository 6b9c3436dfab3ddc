"""The expected-waveform model: Monte Carlo agreement with the explicit engine, its own
convergence, and the properties the sampler relies on."""

import itertools

import numpy as np
import pytest

import forward as fw
from forward.examples import example_stand
from forward.expected import (
    CONVERGED,
    DEFAULT_FREE,
    MIX_FIELDS,
    ExpectedWaveformModel,
    ModelSettings,
)
from forward.expected.grid import anchor_period
from forward.expected.settings import GRID_BLEND_SD_CELLS
from forward.realise import realise, scene_extras

INSTRUMENT = fw.instrument_preset("gedi", footprint_sigma_m=2.5)


_params = example_stand


MC_CASES = {
    "cone": _params(shape_mix="cone"),
    "ellipsoid": _params(shape_mix="ellipsoid"),
    "hemi-ellipsoid": _params(shape_mix="hemi-ellipsoid", height_family="lognormal"),
    "cylinder": _params(shape_mix="cylinder", density=300.0, favd=0.5),
    "mixed two-tier": _params(
        shape_mix={"cone": 0.3, "ellipsoid": 0.7},
        height_family="truncnorm",
        cohort2_fraction=0.6,
        cohort2_height_mean=6.0,
        cohort2_height_sd=1.5,
        cohort2_shape_mix="cone",
        density=900.0,
    ),
    "understory": _params(
        shape_mix="ellipsoid", density=400.0, understory_height=2.0, understory_lai=1.0
    ),
}


@pytest.mark.parametrize("case", sorted(MC_CASES))
def test_mean_of_explicit_realisations_matches_expectation(case):
    """E[engine(realise(θ))] = model(θ): bins and blocks within their Monte Carlo error."""
    params = MC_CASES[case]
    sim = fw.WaveformSimulator(INSTRUMENT, fw.AccuracySettings(radial_nodes=6, angular_nodes=12))
    heights = sim.default_heights(32.0, 0.0)
    model = ExpectedWaveformModel(INSTRUMENT, heights, params, settings=CONVERGED)
    expected = model(params)[0]
    ground, understory, rho_v = scene_extras(params)
    rng = np.random.default_rng(20001)
    side = 2 * (sim.footprint_radius + 6.0)
    n = 300
    runs = np.array(
        [
            sim.simulate(
                realise(params, side, rng, origin=(-side / 2, -side / 2)),
                (0.0, 0.0),
                heights=heights,
                ground=ground,
                canopy_reflectance=rho_v,
                understory=understory,
            ).samples
            for _ in range(n)
        ]
    )
    mean, se = runs.mean(0), runs.std(0, ddof=1) / np.sqrt(n)
    # bins with a usable standard error (elsewhere both are ~0)
    usable = se > 0.05 * se.max()
    z = (mean - expected)[usable] / se[usable]
    assert np.max(np.abs(z)) < 4.5, (case, np.round(z, 2))
    # contiguous blocks: the sums of several bins have errors of their own
    starts = np.linspace(0, heights.size, 9).astype(int)[:-1]
    blocks = np.add.reduceat(runs, starts, axis=1)
    block_se = blocks.std(0, ddof=1) / np.sqrt(n)
    block_z = (blocks.mean(0) - np.add.reduceat(expected, starts)) / np.maximum(block_se, 1e-12)
    # blocks fed only by rare tall trees have skewed, underestimated errors: leave them out
    usable = block_se > 0.1 * block_se.max()
    assert np.max(np.abs(block_z[usable])) < 4.0, (case, np.round(block_z, 2))
    # the total energy ρv(1 − P̄(0)) + ρg·P̄(0)
    total_z = (runs.sum(1).mean() - expected.sum()) / (runs.sum(1).std(ddof=1) / np.sqrt(n))
    assert abs(total_z) < 4.0


def _batch(model, rng, n=16):
    theta = np.repeat(model.vector(model.template)[None, :], n, axis=0)
    theta *= 1.0 + 0.15 * rng.uniform(-1, 1, theta.shape)
    theta[:, model.parameter_names.index("ground_elevation")] = rng.uniform(-1, 1, n)
    return theta


def test_quadrature_converges_to_reference():
    params = MC_CASES["mixed two-tier"]
    sim = fw.WaveformSimulator(INSTRUMENT)
    heights = sim.default_heights(30.0, -3.0)
    rng = np.random.default_rng(5)
    reference = ExpectedWaveformModel(INSTRUMENT, heights, params, settings=CONVERGED)
    theta = _batch(reference, rng)
    ref = reference(theta)

    def error(**settings):
        model = ExpectedWaveformModel(
            INSTRUMENT, heights, params, settings=ModelSettings(**settings)
        )
        return np.max(np.abs(model(theta) - ref).sum(1) / ref.sum(1))

    radial = [error(radial_nodes=j, height_nodes=256, depth_nodes=None) for j in (2, 4, 8, 16)]
    assert all(b < a for a, b in itertools.pairwise(radial)), radial
    assert radial[-1] < 1e-4
    grid = [error(radial_nodes=32, height_nodes=h, depth_nodes=None) for h in (8, 16, 32, 64)]
    assert all(b < a for a, b in itertools.pairwise(grid)), grid
    assert grid[-1] < 1e-4
    depth = [error(radial_nodes=32, height_nodes=256, depth_nodes=d) for d in (8, 16, 32, 64)]
    # a coarse grid hands the cohorts it cannot resolve (sd under two cells) to exact depths
    assert max(depth) < 5e-4, depth
    assert error() < 2e-3  # the defaults


def test_understory_on_the_fast_grid_path_matches_the_converged_model():
    # the understory is added to the grid path layer by layer below its top; a layer
    # taller than some trees and a zero-LAI row are in the batch
    params = MC_CASES["understory"]
    sim = fw.WaveformSimulator(INSTRUMENT)
    heights = sim.default_heights(30.0, -3.0)
    free = (*DEFAULT_FREE, "understory_height", "understory_lai")
    reference = ExpectedWaveformModel(INSTRUMENT, heights, params, free, settings=CONVERGED)
    theta = _batch(reference, np.random.default_rng(8))
    names = reference.parameter_names
    theta[0, names.index("understory_lai")] = 0.0
    theta[1, names.index("understory_height")] = 12.0
    ref = reference.evaluate(theta)
    fast = ExpectedWaveformModel(INSTRUMENT, heights, params, free).evaluate(theta)
    error = np.abs(fast.samples - ref.samples).sum(1) / ref.samples.sum(1)
    assert np.max(error) < 1e-3, error
    np.testing.assert_allclose(fast.gap_ground, ref.gap_ground, rtol=1e-4)


def test_batch_shape_and_invalid_rows_are_masked_not_raised():
    params = MC_CASES["cone"]
    heights = fw.WaveformSimulator(INSTRUMENT).default_heights(30.0)
    model = ExpectedWaveformModel(INSTRUMENT, heights, params)
    theta = _batch(model, np.random.default_rng(1), n=6)
    theta[1, 0] = -5.0  # negative density
    theta[2, 1] = np.nan  # height mean
    theta[3, model.parameter_names.index("crown_length_ratio")] = 1.5
    out = model.evaluate(theta)
    assert out.samples.shape == (6, heights.size)
    assert np.all(np.isfinite(out.samples))
    assert out.valid.tolist() == [True, False, False, False, True, True]
    assert np.all(out.samples[~out.valid] == 0.0)
    assert np.array_equal(model.valid(theta), out.valid)
    # a batch of parameter objects gives the same rows as their vectors
    objects = model([params, params.with_values(density=300.0)])
    vectors = model(
        np.array([model.vector(params), model.vector(params.with_values(density=300.0))])
    )
    np.testing.assert_allclose(objects, vectors)


@pytest.mark.parametrize("case", ["mixed two-tier", "understory"])
def test_a_rows_waveform_does_not_depend_on_the_other_rows_of_its_batch(case):
    # the sampler's target must be one density: the grid a batch shares reaches beyond
    # every row's canopy, so a taller row beside it changes nothing (it changed the
    # two-tier stand's samples by 2e-6 of their peak)
    params = MC_CASES[case]
    heights = fw.WaveformSimulator(INSTRUMENT).default_heights(40.0, -3.0)
    model = ExpectedWaveformModel(INSTRUMENT, heights, params)
    theta = _batch(model, np.random.default_rng(9), n=12)
    theta[:, model.parameter_names.index("height_mean")] *= np.linspace(0.6, 1.6, 12)
    batch = model.evaluate(theta)
    for row in range(theta.shape[0]):
        alone = model.evaluate(theta[row : row + 1])
        peak = np.max(alone.samples)
        np.testing.assert_allclose(batch.samples[row], alone.samples[0], rtol=0, atol=1e-9 * peak)
        np.testing.assert_allclose(batch.gap_ground[row], alone.gap_ground[0], rtol=1e-12)


def test_free_shape_mix_reproduces_fixed_mixes_and_masks_bad_mixes():
    heights = fw.WaveformSimulator(INSTRUMENT).default_heights(30.0, -2.0)
    params = _params(shape_mix={"cone": 0.3, "ellipsoid": 0.7})
    free = ExpectedWaveformModel(INSTRUMENT, heights, params, free=DEFAULT_FREE + MIX_FIELDS)
    assert free.ndim == len(DEFAULT_FREE) + 4
    assert free.parameter_names[-4:] == MIX_FIELDS
    cone = params.with_values(shape_mix="cone")
    theta = np.array([free.vector(params), free.vector(cone)] + [free.vector(params)] * 3)
    mix = [free.parameter_names.index(name) for name in MIX_FIELDS]
    theta[2, mix] = [0.3, 0.6, 0.0, 0.0]  # sums to 0.9
    theta[3, mix] = [1.2, -0.2, 0.0, 0.0]  # a negative fraction
    theta[4, mix] = [np.nan, 0.7, 0.0, 0.0]
    out = free.evaluate(theta)
    assert out.valid.tolist() == [True, True, False, False, False]
    assert np.all(np.isfinite(out.samples)) and np.all(out.samples[2:] == 0.0)
    for row, fixed in ((0, params), (1, cone)):
        expected = ExpectedWaveformModel(INSTRUMENT, heights, fixed)(fixed)[0]
        np.testing.assert_allclose(out.samples[row], expected, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("case", sorted(MC_CASES))
def test_numba_and_numpy_backends_agree(case):
    pytest.importorskip("numba")
    params = MC_CASES[case]
    heights = fw.WaveformSimulator(INSTRUMENT).default_heights(30.0, -3.0)
    out = {}
    for backend in ("numpy", "numba"):
        settings = ModelSettings(backend=backend)
        model = ExpectedWaveformModel(INSTRUMENT, heights, params, settings=settings)
        assert model.backend == backend
        theta = _batch(model, np.random.default_rng(7), n=5)
        out[backend] = model(theta), model.gap(theta, [0.0, 1.0, 4.0, 12.0])
    for numpy_result, numba_result in zip(out["numpy"], out["numba"]):
        np.testing.assert_allclose(numba_result, numpy_result, rtol=1e-10, atol=1e-14)


def test_extreme_valid_rows_stay_finite():
    """Opaque crowns (large FAVD), a heavy height tail and a far ground: finite output."""
    heights = fw.WaveformSimulator(INSTRUMENT).default_heights(30.0, -3.0)
    params = _params(height_family="lognormal", shape_mix={"cone": 0.5, "ellipsoid": 0.5})
    for backend in ("numpy", "auto"):
        model = ExpectedWaveformModel(
            INSTRUMENT, heights, params, settings=ModelSettings(backend=backend)
        )
        theta = np.repeat(model.vector(params)[None, :], 4, axis=0)
        index = model.parameter_names.index
        theta[0, index("favd")] = 400.0
        theta[1, index("height_sd")] = 200.0  # tallest trees far above the window
        theta[2, index("ground_elevation")] = 500.0
        theta[3, index("crown_length_ratio")] = 1.0
        out = model.evaluate(theta)
        assert out.valid.all() and np.all(np.isfinite(out.samples)), backend
        assert np.all((out.gap_ground > 0) & (out.gap_ground < 1))  # gaps between crowns
        assert out.samples[2].sum() == 0.0  # everything above the window


def test_energy_budget_and_limits():
    heights = fw.WaveformSimulator(INSTRUMENT).default_heights(35.0, -2.0)
    params = MC_CASES["ellipsoid"]
    model = ExpectedWaveformModel(INSTRUMENT, heights, params)
    out = model.evaluate(params)
    p0 = out.gap_ground[0]
    total = params.canopy_reflectance * (1 - p0) + params.ground_reflectance * p0
    assert out.samples.sum() == pytest.approx(total, rel=1e-6)
    # no trees: the ground pulse alone, of area ρg
    bare = model.evaluate(params.with_values(density=0.0))
    assert np.all(bare.canopy == 0) and bare.samples.sum() == pytest.approx(0.3, rel=1e-6)
    assert heights[np.argmax(bare.samples)] == pytest.approx(0.0, abs=heights[1] - heights[0])
    # a dense opaque stand hides the ground
    dense = model.evaluate(params.with_values(density=20000.0, favd=5.0))
    assert dense.gap_ground[0] < 1e-6


def test_ground_elevation_shifts_exactly_by_whole_anchor_periods():
    heights = fw.WaveformSimulator(INSTRUMENT).default_heights(30.0, -5.0)
    params = MC_CASES["hemi-ellipsoid"]
    model = ExpectedWaveformModel(INSTRUMENT, heights, params)
    dz = INSTRUMENT.bin_height
    period = anchor_period(model._per_cell, model.oversampling) // model.oversampling  # bins
    theta = np.repeat(model.vector(params)[None, :], 3, axis=0)
    g = model.parameter_names.index("ground_elevation")
    theta[:, g] = [0.0, period * dz, 0.37 * dz]
    w = model(theta)
    np.testing.assert_allclose(w[1, period:], w[0, :-period], atol=1e-12)
    centroid = (w * heights).sum(1) / w.sum(1)
    assert centroid[2] - centroid[0] == pytest.approx(0.37 * dz, rel=1e-3)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_waveform_is_continuous_in_the_ground_elevation(backend):
    """Across every bin edge, the grid path's waveform moves by the tiny shift alone, even
    for trees of nearly one height, whose crowns the depth grid resolves worst (a grid
    anchored on each bin edge moved by 0.4 % of the peak there)."""
    if backend == "numba":
        pytest.importorskip("numba")
    heights = fw.WaveformSimulator(INSTRUMENT).default_heights(30.0, -5.0)
    params = MC_CASES["cone"].with_values(height_sd=0.15)
    settings = ModelSettings(backend=backend)
    model = ExpectedWaveformModel(INSTRUMENT, heights, params, settings=settings)
    dz, origin = INSTRUMENT.bin_height, heights[0] - INSTRUMENT.bin_height / 2
    edges = origin + dz * np.arange(20, 20 + 2 * anchor_period(model._per_cell, 1))
    theta = np.repeat(model.vector(params)[None, :], 2 * edges.size, axis=0)
    theta[:, model.parameter_names.index("ground_elevation")] = np.repeat(edges, 2) + np.tile(
        [-1e-9, 1e-9], edges.size
    )
    w = model(theta)
    change = np.abs(w[1::2] - w[::2]).max(axis=1) / w.max()
    assert change.max() < 1e-6


def test_narrow_height_distributions_take_exact_depths_and_stay_continuous():
    """Below one grid cell of height sd the fast model is the exact-depth one; at both ends
    of the blend into the grid the waveform moves by the tiny change of sd alone."""
    heights = fw.WaveformSimulator(INSTRUMENT).default_heights(30.0, -5.0)
    params = MC_CASES["cone"]
    fast = ExpectedWaveformModel(INSTRUMENT, heights, params)
    exact = ExpectedWaveformModel(
        INSTRUMENT, heights, params, settings=ModelSettings(depth_nodes=None)
    )
    cell = fast._per_cell * fast.layer_height
    low, high = GRID_BLEND_SD_CELLS
    sds = cell * np.array([0.3, low - 1e-9, low + 1e-9, high - 1e-9, high + 1e-9])
    theta = np.repeat(fast.vector(params)[None, :], sds.size, axis=0)
    theta[:, fast.parameter_names.index("height_sd")] = sds
    w, reference = fast(theta), exact(theta)
    np.testing.assert_allclose(w[:2], reference[:2], rtol=0, atol=1e-12 * reference.max())
    assert np.abs(w[2] - w[1]).max() < 1e-6 * w.max()
    assert np.abs(w[4] - w[3]).max() < 1e-6 * w.max()
    # the grid alone above the blend, within its accuracy of a broad canopy
    assert np.abs(w[4] - reference[4]).max() < 1e-3 * reference.max()


def test_measured_pulse_replaces_gaussian():
    gauss = fw.instrument_preset("gedi", footprint_sigma_m=2.5)
    t = np.arange(-160, 161) * 0.25  # ns, ±6 sd
    sigma_ns = 15.0 / 2.35482
    samples = np.exp(-0.5 * (t / sigma_ns) ** 2)
    measured = gauss.with_overrides(pulse=fw.MeasuredPulse(samples, 0.25))
    heights = fw.WaveformSimulator(gauss).default_heights(30.0)
    params = MC_CASES["cone"]
    a = ExpectedWaveformModel(gauss, heights, params)(params)
    b = ExpectedWaveformModel(measured, heights, params)(params)
    assert np.abs(a - b).sum() / a.sum() < 2e-3
