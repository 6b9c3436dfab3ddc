"""The grid-of-columns engine: compiled kernel against its numpy reference, and the
engine against the brute-force reference model where crowns overlap."""

import numpy as np
import pytest

import forward as fw
from forward.explicit import column_kernel_numba
from forward.explicit.column_grid import ColumnGrid, CrownSet, crown_node_ranges
from lidarinv.testing.reference_model import reference_waveform

needs_numba = pytest.mark.skipif(not column_kernel_numba.AVAILABLE, reason="needs numba")


def overlapping_stand(rng, n, half_width, radius=(1.5, 2.5), favd=1.5, shapes=fw.SHAPE_NAMES):
    """``n`` crowns on a square of ±``half_width`` m: dense enough to overlap heavily."""
    height = rng.uniform(8.0, 16.0, n)
    return fw.Stand.from_arrays(
        x=rng.uniform(-half_width, half_width, n),
        y=rng.uniform(-half_width, half_width, n),
        height=height,
        crown_length=rng.uniform(0.4, 0.8, n) * height,
        crown_radius=rng.uniform(*radius, n),
        favd=favd,
        shape=rng.choice(list(shapes), n),
    )


def slab_stand(rng, n, half_width, radius, favd):
    """``n`` slab-like cylinders 0.5–3 m deep and ``radius`` (low, high) m wide."""
    return fw.Stand.from_arrays(
        x=rng.uniform(-half_width, half_width, n), y=rng.uniform(-half_width, half_width, n),
        height=rng.uniform(5, 30, n), crown_length=rng.uniform(0.5, 3.0, n),
        crown_radius=rng.uniform(*radius, n), favd=favd, shape="cylinder",
    )  # fmt: skip


def relative_l1(samples, reference):
    return np.abs(samples - reference).sum() / reference.sum()


SCENES = {
    "overlap": dict(),
    "hot spot k=2": dict(hotspot_k=2.0),
    "slope": dict(ground=fw.Ground(0.3, slope_deg=25.0, aspect_deg=40.0)),
    "understory": dict(understory=fw.UniformUnderstory(2.0, 1.2)),
}


@needs_numba
@pytest.mark.parametrize("scene", SCENES)
def test_compiled_kernel_equals_numpy_reference(scene, rng):
    options = dict(SCENES[scene])
    inst = fw.instrument_preset("gedi", hotspot_k=options.pop("hotspot_k", 1.0))
    stand = overlapping_stand(rng, 150, 25.0)
    runs = [
        fw.WaveformSimulator(inst, fw.AccuracySettings(backend=backend)).simulate(
            stand, center=(1.0, -2.0), **options
        )
        for backend in ("numba", "numpy")
    ]
    compiled, reference = runs
    assert compiled.settings["backend"] == "numba"
    assert reference.settings["backend"] == "numpy"
    scale = reference.samples.max()
    np.testing.assert_allclose(compiled.samples, reference.samples, rtol=0, atol=1e-13 * scale)
    for name in ("gap", "crown_volume", "foliage_area"):
        np.testing.assert_allclose(getattr(compiled, name), getattr(reference, name), atol=1e-13)
    assert compiled.ground_gap == pytest.approx(reference.ground_gap, rel=1e-12, abs=1e-15)


@needs_numba
@pytest.mark.parametrize("even", [False, True], ids=["stretched nodes", "even nodes"])
def test_compiled_crown_node_ranges_equal_numpy_reference(rng, even):
    """Crowns inside, across and beyond the grid, some with an edge exactly on a node or
    an ulp beside one: the compiled search gives the reference's first and last nodes."""
    grid = ColumnGrid.build(5.0, 0.7, 1e-3, **({"stretch": None} if even else {}))
    n = 600
    x, y = rng.uniform(-1.5, 1.5, (2, n)) * grid.radius
    radius = rng.uniform(0.0, 4.0, n)
    on_node = grid.nodes[rng.integers(0, grid.nodes.size, 60)]
    x[:60], radius[:60] = on_node + 1.0, 1.0  # x − r lands on a node, or an ulp off it
    x[60:120] = np.nextafter(grid.nodes[rng.integers(0, grid.nodes.size, 60)], np.inf)
    radius[60:120] = 0.0
    x[120:130] = grid.nodes[0] - 1.0  # wholly before the first node
    crowns = CrownSet(
        x=x, y=y, radius=radius, shape=np.zeros(n, np.int64), base=np.zeros(n),
        length=np.ones(n), extinction=np.ones(n), favd=np.ones(n),
    )  # fmt: skip
    reference = crown_node_ranges(grid, crowns)
    compiled = column_kernel_numba.crown_node_ranges(grid, crowns)
    for got, want in zip(compiled, reference):
        np.testing.assert_array_equal(got, want)
    assert np.any(compiled[1] < compiled[0])  # crowns that hold no node are kept so


@needs_numba
def test_compiled_kernel_handles_many_wide_crowns():
    """A hundred and twenty slab-like crowns over every column (walked layer by layer,
    not run by run) give the numpy reference's numbers."""
    stand = slab_stand(np.random.default_rng(5), 120, 10.0, (15.0, 30.0), 0.05)
    inst = fw.instrument_preset("gedi", footprint_sigma_m=2.0)
    compiled, reference = (
        fw.WaveformSimulator(inst, fw.AccuracySettings(backend=b)).simulate(stand)
        for b in ("numba", "numpy")
    )
    np.testing.assert_allclose(compiled.samples, reference.samples, atol=1e-13)


@pytest.mark.parametrize("scene", ["overlap", "hot spot k=2", "slope", "understory"])
def test_engine_matches_reference_model_where_crowns_overlap(scene):
    """About twenty crowns over a narrow beam, each overlapping several others."""
    rng = np.random.default_rng(
        {"overlap": 1, "hot spot k=2": 2, "slope": 3, "understory": 4}[scene]
    )
    options = dict(SCENES[scene])
    inst = fw.instrument_preset(
        "gedi", footprint_sigma_m=1.5, pulse_fwhm_ns=6.0, hotspot_k=options.pop("hotspot_k", 1.0)
    )
    stand = overlapping_stand(rng, 40, 7.0)
    ground = options.get("ground", fw.Ground(0.3))
    accuracy = fw.AccuracySettings(tolerance=3e-4, truncation_tolerance=1e-3)
    wf = fw.WaveformSimulator(inst, accuracy).simulate(stand, **options)
    expected, ground_gap = reference_waveform(
        stand, inst, wf.heights, spacing=0.04, fine=0.01, tolerance=1e-3, ground=ground,
        understory=options.get("understory"),
    )  # fmt: skip
    assert wf.ground_gap == pytest.approx(ground_gap, rel=1e-2)  # the reference: ±0.7 %
    assert relative_l1(wf.samples, expected) < 4e-3


def test_tighter_tolerance_converges_to_the_reference_model():
    rng = np.random.default_rng(11)
    inst = fw.instrument_preset("gedi", footprint_sigma_m=1.5, pulse_fwhm_ns=6.0, hotspot_k=2.0)
    stand = overlapping_stand(rng, 40, 7.0, shapes=("cone",))
    heights = fw.WaveformSimulator(inst).simulate(stand).heights
    expected, _ = reference_waveform(stand, inst, heights, spacing=0.03, fine=0.01)
    errors = [
        relative_l1(
            fw.WaveformSimulator(inst, tol).simulate(stand, heights=heights).samples, expected
        )
        for tol in (3e-2, 3e-3, 3e-4)
    ]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 2e-3


def test_column_weights_are_the_truncated_footprint():
    grid = ColumnGrid.build(5.5, 0.3, 1e-3)
    x, y = np.meshgrid(grid.nodes, grid.nodes, indexing="ij")
    inside = x**2 + y**2 <= grid.radius**2
    omega = np.outer(grid.weights, grid.weights)[inside]
    assert omega.sum() == pytest.approx(1.0, rel=1e-12)
    assert grid.n_columns == inside.sum()
    # second moment of the truncated Gaussian: σ²(1 − r²/(2σ²)·tol/(1 − tol))
    r2 = x[inside] ** 2 + y[inside] ** 2
    tol, sigma = 1e-3, 5.5
    expected = 2 * sigma**2 * (1 - (grid.radius**2 / (2 * sigma**2)) * tol / (1 - tol))
    assert (omega * r2).sum() == pytest.approx(expected, rel=2e-3)
    # densest at the beam centre, spaced as asked there
    steps = np.diff(grid.nodes)
    assert steps.min() == pytest.approx(0.3, rel=0.05) and steps.max() > 2 * steps.min()


@pytest.mark.parametrize("accuracy", [1e-3, "1e-3", fw.AccuracySettings(tolerance=1e-3)])
def test_accuracy_may_be_given_as_a_tolerance(gedi, accuracy):
    sim = fw.WaveformSimulator(gedi, accuracy)
    assert sim.accuracy.tolerance == 1e-3 and sim.scheme == "columns"
    assert sim.accuracy.footprint_tolerance == pytest.approx(1e-4)
    # the ground's own columns reach furthest: their truncation is 0.003 × tolerance
    assert sim.footprint_radius == pytest.approx(5.5 * np.sqrt(-2 * np.log(3e-6)))


def test_node_counts_select_the_per_crown_quadrature(gedi):
    sim = fw.WaveformSimulator(gedi, fw.AccuracySettings(radial_nodes=6, angular_nodes=12))
    assert sim.scheme == "crowns" and sim.accuracy.footprint_tolerance == 1e-3
    wf = sim.simulate(fw.Stand.from_arrays(x=[1.0], y=[0.0], height=[15.0], crown_length=[6.0],
                                           crown_radius=[2.0], favd=0.5))  # fmt: skip
    assert wf.settings["scheme"] == "crowns" and wf.settings["radial_nodes"] == 6


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: fw.AccuracySettings(tolerance=0.0), "tolerance"),
        (lambda: fw.AccuracySettings(tolerance=0.7), "tolerance"),
        (lambda: fw.AccuracySettings(column_spacing=-0.1), "column_spacing"),
        (lambda: fw.AccuracySettings(backend="cuda"), "backend"),
        (lambda: fw.WaveformSimulator(fw.instrument_preset("gedi"), "fine"), "tolerance"),
    ],
)
def test_bad_accuracy_names_the_problem(build, message):
    with pytest.raises(ValueError, match=message):
        build()


@pytest.mark.parametrize("preset", ["slicer", "lvis", "gedi"])
def test_default_layers_keep_the_quarter_sigma_rule(preset):
    """At the default tolerance the fine layers are those of earlier versions (≤ σz/4);
    a tighter tolerance thins them as its square root."""
    inst = fw.instrument_preset(preset)
    sigma = inst.pulse.sigma_m
    default = fw.WaveformSimulator(inst)
    assert default.oversampling == max(1, int(np.ceil(4 * inst.bin_height / sigma - 1e-9)))
    tight = fw.WaveformSimulator(inst, 1e-5)
    assert tight.layer_height <= sigma * np.sqrt(25 * 1e-5) < default.layer_height


def test_column_spacing_follows_the_tolerance():
    accuracy = fw.AccuracySettings()
    base = accuracy.column_spacing_for(5.5, 2.0)
    tighter = fw.AccuracySettings(tolerance=accuracy.tolerance / 8).column_spacing_for(5.5, 2.0)
    assert tighter == pytest.approx(base / 4)  # s ∝ tolerance^(2/3)
    assert accuracy.column_spacing_for(5.5 * 8, 2.0) == pytest.approx(4 * base)  # ∝ σf^(2/3)
    assert fw.AccuracySettings(column_spacing=0.4).column_spacing_for(5.5, 2.0) == 0.4


def test_numpy_kernel_memory_does_not_grow_with_crown_size():
    """Tiles bound the numpy reference's work arrays: 300 slabs 8–60 m wide over a 2 m
    beam (which made the per-crown quadrature allocate 1.4 GB) stay within tens of MB."""
    import tracemalloc

    stand = slab_stand(np.random.default_rng(30), 300, 30.0, (4.0, 30.0), 0.2)
    sim = fw.WaveformSimulator(
        fw.instrument_preset("gedi", footprint_sigma_m=2.0), fw.AccuracySettings(backend="numpy")
    )
    prepared = sim.prepare(stand)
    tracemalloc.start()
    sim.simulate(prepared)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 100e6


def test_footprints_under_few_crowns_get_closer_columns(gedi):
    """Edge errors average over the crowns sharing the footprint: with fewer than
    (σf/R)² of them the columns are closer (and few crowned columns cost little)."""
    one = fw.Stand.from_arrays(x=[1.0], y=[0.0], height=[15.0], crown_length=[6.0],
                               crown_radius=[2.0], favd=0.5)  # fmt: skip
    sim = fw.WaveformSimulator(gedi)
    crowns = sim.prepare(one).crowns_near(0.0, 0.0, sim.footprint_radius, fw.Ground())
    assert crowns.effective_count(gedi.footprint_sigma_m) == pytest.approx(1.0)
    many = overlapping_stand(np.random.default_rng(3), 600, 25.0, radius=(2.0, 2.0))
    assert (
        sim.simulate(one).settings["column_spacing_m"]
        < 0.8 * sim.simulate(many).settings["column_spacing_m"]
    )


def closed_cone_stand(rng, sigma):
    """3000 cones/ha, 12–25 m tall, 1.5–2.5 m wide, FAVD 1.5, over a footprint of σf =
    ``sigma`` m and its rim: P̄ at the ground 1–6 %, most of it between crown edges."""
    half_width = 5.7 * sigma + 2.5
    n = rng.poisson(0.3 * (2 * half_width) ** 2)
    height = rng.uniform(12.0, 25.0, n)
    return fw.Stand.from_arrays(
        x=rng.uniform(-half_width, half_width, n), y=rng.uniform(-half_width, half_width, n),
        height=height, crown_length=0.6 * height, crown_radius=rng.uniform(1.5, 2.5, n),
        favd=1.5, shape="cone",
    )  # fmt: skip


@pytest.mark.parametrize(("hotspot_k", "seed"), [(1.0, 1), (2.0, 0), (2.0, 3)])
def test_default_ground_energy_matches_reference_model_under_closed_canopy(hotspot_k, seed):
    """The ground gap's relative error is largest where the canopy is closed: the
    defaults keep it within 0.3 % of the brute-force model (0.05 m columns, within
    0.05 % of the converged engine here) on dense overlapping cones, with and without
    the two-way hot spot (the defaults of earlier versions erred by 0.5–0.6 % on the
    hot-spot stands)."""
    inst = fw.instrument_preset("gedi", footprint_sigma_m=3.0, hotspot_k=hotspot_k)
    stand = closed_cone_stand(np.random.default_rng(seed), 3.0)
    wf = fw.WaveformSimulator(inst).simulate(stand)
    assert wf.settings["ground_column_spacing_m"] < wf.settings["column_spacing_m"]
    _, ground_gap = reference_waveform(
        stand, inst, wf.heights, spacing=0.05, fine=100.0, tolerance=1e-7, block=20000
    )  # only the ground gap is compared: it needs no fine edges
    assert ground_gap < 0.05
    assert wf.ground_gap == pytest.approx(ground_gap, rel=3e-3)
    assert wf.ground_energy == pytest.approx(0.3 * ground_gap, rel=3e-3)


def test_canopy_and_ground_energy_add_up_with_the_grounds_own_columns(gedi):
    """The canopy returns are scaled to 1 − P̄(0) of the ground's columns, so the
    energy identity ρv(1 − P̄(0)) + ρg·P̄(0) holds in the samples."""
    stand = overlapping_stand(np.random.default_rng(8), 400, 25.0)
    wf = fw.WaveformSimulator(gedi).simulate(stand)
    rho_v = wf.settings["canopy_reflectance"]
    assert wf.canopy.sum() == pytest.approx(rho_v * (1.0 - wf.ground_gap), rel=1e-6)
    assert wf.ground.sum() == pytest.approx(0.3 * wf.ground_gap, rel=1e-6)
    # given a column spacing, the ground shares the profiles' columns
    same = fw.WaveformSimulator(gedi, fw.AccuracySettings(column_spacing=0.3)).simulate(stand)
    assert same.settings["ground_column_spacing_m"] == same.settings["column_spacing_m"]


def test_ground_columns_are_closer_and_reach_further():
    accuracy = fw.AccuracySettings()
    assert accuracy.ground_spacing_for(5.5, 2.0) == pytest.approx(
        0.5 * accuracy.column_spacing_for(5.5, 2.0)
    )
    assert accuracy.ground_tolerance < accuracy.footprint_tolerance
    cones = fw.SHAPE_NAMES.index("cone")
    assert accuracy.column_spacing_for(5.5, 2.0, shapes=[cones]) > accuracy.column_spacing_for(
        5.5, 2.0, shapes=[cones, fw.SHAPE_NAMES.index("cylinder")]
    )


def test_stem_search_scans_first_then_uses_a_tree(gedi):
    """A stand serving one footprint is scanned; one serving several builds a tree. Both
    find exactly the stems a direct distance test finds, and the waveforms of a footprint
    simulated first and again agree to rounding."""
    stand = overlapping_stand(np.random.default_rng(6), 400, 40.0)
    sim = fw.WaveformSimulator(gedi)
    prepared = sim.prepare(stand)
    centres = [(0.0, 0.0), (7.5, -12.0), (0.0, 0.0)]
    for cx, cy in centres:
        expected = np.flatnonzero(np.hypot(stand.x - cx, stand.y - cy) <= 15.0)
        np.testing.assert_array_equal(prepared.stems_within(cx, cy, 15.0), expected)
    assert "tree" in prepared._search
    heights = np.arange(-5.0, 20.0, gedi.bin_height)
    scanned = sim.simulate(sim.prepare(stand), heights=heights).samples
    searched = sim.simulate(prepared, heights=heights).samples
    np.testing.assert_allclose(scanned, searched, rtol=1e-12, atol=1e-15)
