"""Every compiled kernel against its numpy twin, through the one ``backend=`` switch and
the one check of lidarinv.testing: the expected model's processes (depth, point stems,
grid assembly, the grid path in one call, ground), the stand mapping's identities, the
two-storey mixture's cuts and the ridge maps. The likelihood and the RH kernels are
checked against their references in tests/lidarinv/inference/likelihood/test_gaussian.py,
the stand mapping as a whole in tests/lidarinv/inference/model/test_stand.py."""

import numpy as np
import pytest

import forward as fw
from forward.examples import example_stand
from forward.expected import (
    ExpectedWaveformModel,
    ModelSettings,
    depth,
    grid,
    ground,
    physical_rows,
)
from forward.expected.settings import GRID_UNDERSHOOT
from forward.height_families import HEIGHT_DISTRIBUTIONS
from lidarinv.inference.model import coordinates
from lidarinv.inference.model.mixture_cut import mixture_cut
from lidarinv.inference.model.parameters import DEFAULT_STRUCTURE_PRIORS, default_space
from lidarinv.inference.model.stand import TOP_SDS, StandMapping, default_template
from lidarinv.inference.model.stand_columns import DOMINANT_PER_HA, stand_columns
from lidarinv.inference.model.two_cohort import TwoCohortMapping
from lidarinv.testing import assert_backends_agree, assert_fast_path

pytest.importorskip("numba")

GEDI = fw.instrument_preset("gedi")
HEIGHTS = np.arange(-8.0, 40.0, GEDI.bin_height)

#: Templates exercising every branch: two cohorts and an understory; a stand conditioned
#: on its tallest stem (apex stems of one height); a spheroid-only stand.
TEMPLATES = {
    "two cohorts, understory": (
        example_stand(
            shape_mix={"cone": 0.4, "ellipsoid": 0.6},
            cohort2_fraction=0.4,
            cohort2_height_mean=6.0,
            cohort2_height_sd=1.5,
            cohort2_shape_mix="hemi-ellipsoid",
            understory_height=1.5,
            understory_lai=0.8,
        ),
        fw.DEFAULT_FREE,
    ),
    "tallest stem": (
        example_stand(height_family="truncnorm", shape_mix={"cone": 0.5, "ellipsoid": 0.5}),
        (*fw.DEFAULT_FREE, "height_cap", "apex_density"),
    ),
    "cylinders": (example_stand(shape_mix="cylinder", height_family="weibull"), fw.DEFAULT_FREE),
}


def _case(name, n=7):
    """A numpy-backend model, full parameter vectors around its template (the first row the
    template itself) and their cohorts."""
    template, free = TEMPLATES[name]
    model = ExpectedWaveformModel(GEDI, HEIGHTS, template, free, ModelSettings(backend="numpy"))
    rng = np.random.default_rng(3)
    base = model.full_vector(template)
    full = np.repeat(base[None, :], n, axis=0)
    for field in ("density", "height_mean", "height_sd", "favd", "crown_length_ratio"):
        full[1:, fw.VECTOR_FIELDS.index(field)] *= rng.uniform(0.7, 1.3, n - 1)
    full[:, fw.VECTOR_FIELDS.index("ground_elevation")] = rng.uniform(-1.0, 1.0, n)
    if "height_cap" in free:
        cap = full[:, fw.VECTOR_FIELDS.index("height_mean")] + rng.uniform(0.0, 4.0, n)
        full[:, fw.VECTOR_FIELDS.index("height_cap")] = cap
        full[:, fw.VECTOR_FIELDS.index("apex_density")] = rng.uniform(0.0, 90.0, n)
    assert model.valid(full[:, model._free_index]).all()
    return model, full, model._cohorts(full)


@pytest.mark.parametrize("name", sorted(TEMPLATES))
def test_tree_depth_kernels_equal_the_numpy_path(name):
    """Each cohort's depth, the apex stems' and their sum, at heights from the ground to
    above the tallest tree (z ≥ 0)."""
    model, v, cohorts = _case(name)
    z = np.linspace(0.0, 35.0, 90)[None, :] + np.zeros((v.shape[0], 1))
    densities = model._cohort_densities(v, cohorts)
    points = model._point_masses(v, cohorts)
    crowns = model._crown_columns(v)
    tables = model._depth_tables
    tails, a_groups, b_groups = tables
    for pdf, lo, step, stems, w in densities:
        assert_backends_agree(
            depth.add_cohort_depth, pdf, lo, step, stems, *crowns, w, z, np.zeros_like(z),
            tails=tails, a_groups=a_groups, b_groups=b_groups, rtol=1e-9, atol=1e-12,
        )  # fmt: skip
    if points is not None:
        stems, height, w = points
        assert_backends_agree(
            depth.add_point_depth, stems, height, *crowns, w, z, np.zeros_like(z), rtol=1e-12
        )
    total = assert_backends_agree(
        depth.tree_depth, densities, points, crowns, z, tables=tables, rtol=1e-9, atol=1e-12
    )
    assert np.all(np.isfinite(total)) and total[:, 0].min() > 0  # trees above the ground


@pytest.mark.parametrize("name", sorted(TEMPLATES))
def test_grid_assembly_and_the_one_call_grid_path_equal_the_numpy_path(name):
    model, v, cohorts = _case(name)
    dz, step = GEDI.bin_height, model._per_cell * model.layer_height
    g = v[:, fw.VECTOR_FIELDS.index("ground_elevation")]
    shift = np.floor((g - model._origin) / dz)
    z0 = model._origin + shift * dz - g
    nodes = 40
    lai = v[:, fw.VECTOR_FIELDS.index("understory_lai")]
    top_u = v[:, fw.VECTOR_FIELDS.index("understory_height")]
    scale_u = np.where(lai > 0, GEDI.extinction_per_favd * lai / top_u, 0.0)
    operator = model._grid_operator(nodes)
    densities, points = model._cohort_densities(v, cohorts), model._point_masses(v, cohorts)
    crowns = model._crown_columns(v)
    z = np.maximum(z0[:, None] + step * np.arange(nodes), 0.0)
    tree = depth.tree_depth(densities, points, crowns, z, backend="numpy")
    layout = (operator, shift, scale_u, top_u, z0, model.layer_height, HEIGHTS.size)
    canopy, gap0, redo = assert_backends_agree(
        grid.assemble_grid, tree, *layout, GRID_UNDERSHOOT, rtol=1e-9, atol=1e-13
    )
    assert not redo.any() and np.all(canopy >= 0) and np.all((gap0 > 0) & (gap0 <= 1))
    assert_backends_agree(
        grid.grid_canopy, densities, points, crowns, z0, step, nodes, operator, shift, scale_u,
        top_u, model.layer_height, HEIGHTS.size, GRID_UNDERSHOOT, tables=model._depth_tables,
        rtol=1e-9, atol=1e-13,
    )  # fmt: skip


def test_gaussian_ground_kernel_equals_the_point_returns():
    """The compiled Gaussian ground (exact ratios from the peak) against the pulse of
    forward.pulse.point_returns, grounds spread wider than the pulse in one batch."""
    rng = np.random.default_rng(4)
    pulse, dz = fw.GaussianPulse(14.0), 0.15
    heights = -20.0 + dz * np.arange(600)
    n = 40
    zg = np.concatenate([rng.uniform(-1.0, 1.0, n - 4), [-12.0, 30.0, 0.037, 0.075]])
    canopy = rng.uniform(0.0, 1e-3, (n, heights.size))
    gap0, rho_v, rho_g = rng.uniform(0.01, 1.0, n), rng.uniform(0.1, 0.6, n), np.full(n, 0.4)
    valid = rng.uniform(size=n) > 0.1
    args = (canopy, gap0, zg, rho_v, rho_g, valid, heights, dz, pulse, pulse.support(1e-12))
    _, _, slow = assert_backends_agree(ground.ground_return, *args, rtol=1e-12, atol=1e-15)
    assert np.all(slow[~valid] == 0.0) and slow[valid].sum(axis=1).min() > 0.0
    # each valid row's ground holds ρg·E[P(0)] (the pulse resolved, its support inside)
    np.testing.assert_allclose(slow[valid].sum(axis=1), (rho_g * gap0)[valid], rtol=1e-9)


@pytest.mark.parametrize("name", sorted(TEMPLATES))
def test_expected_model_backends_agree(name):
    """The whole model: both backends, the fast grid path and the per-edge one."""
    template, free = TEMPLATES[name]
    _, full, _ = _case(name)
    for depth_nodes in (32, None):
        models = {
            backend: ExpectedWaveformModel(
                GEDI,
                HEIGHTS,
                template,
                free,
                ModelSettings(backend=backend, depth_nodes=depth_nodes),
            )
            for backend in ("numba", "numpy")
        }
        theta = full[:, models["numpy"]._free_index]
        assert_fast_path(
            models["numba"].evaluate, models["numpy"].evaluate, theta, rtol=1e-9, atol=1e-13
        )


@pytest.mark.parametrize("shapes", [("cone", "ellipsoid"), ("hemi-ellipsoid", "cylinder")])
def test_stand_identities_compiled_equal_numpy(shapes):
    mapping = StandMapping(default_template(shapes), shapes)
    rng = np.random.default_rng(6)
    v = {name: prior.sample(rng, 300) for name, prior in DEFAULT_STRUCTURE_PRIORS.items()}
    v = {name: values[mapping.valid({**v, "rho_ratio": v["cover"]})] for name, values in v.items()}
    args = (v, 0.0, TOP_SDS, mapping.family, mapping.truncation, mapping._volume, mapping._leaf)
    assert_backends_agree(stand_columns, *args, DOMINANT_PER_HA, rtol=1e-10)


def test_two_storey_cuts_compiled_equal_numpy():
    """Cuts of two-storey mixtures, closed-form and bisected, with the edge cases of the
    tails (none, every stem, beyond every stem, NaN)."""
    mapping = TwoCohortMapping(default_template())
    rng = np.random.default_rng(8)
    n = 400
    v = {
        "top_height": rng.uniform(5.0, 60.0, n),
        "height_sd": rng.uniform(0.3, 8.0, n),
        "cohort2_fraction": rng.uniform(0.0, 1.0, n),
        "cohort2_top_ratio": rng.uniform(0.1, 0.9, n),
        "cohort2_sd_ratio": rng.uniform(0.02, 0.45, n),
    }
    laws = mapping._stacked_laws(mapping.cohort_heights(v))
    tail = 10.0 ** rng.uniform(-9.0, 0.0, n)
    tail[:5] = [0.0, 1.0, 2.0, np.inf, np.nan]
    assert_backends_agree(mixture_cut, mapping.family, laws, tail, rtol=1e-12, atol=1e-9)


def test_ridge_maps_compiled_equal_numpy(nuisance_priors):
    """The ridge maps' values and Jacobians written in place, near the prior and beyond."""
    space = default_space(nuisance_priors)
    rng = np.random.default_rng(11)
    u = space.to_unbounded(space.sample_prior(rng, 500))
    u = np.where(np.isfinite(u), u, 0.0)
    u[250:] += rng.normal(0.0, 3.0, u[250:].shape)
    x, log_jac = space._priors.from_unbounded(u)
    maps = (space._joint, space._base, space._centroid, space._ridge_inputs, TOP_SDS)
    with np.errstate(all="ignore"):
        assert_backends_agree(
            coordinates.ridges_from_unbounded, u, x, log_jac, *maps, space.interception_slope,
            rtol=1e-12, atol=1e-10,
        )  # fmt: skip


@pytest.mark.parametrize("name", sorted(TEMPLATES))
def test_physical_rows_kernel_equals_the_numpy_path(name):
    """Rows broken every way the check looks for: non-finite fields (an infinite cap, with
    and without apex stems), fields on and beyond their bounds, shape fractions off 1, and
    cohort 2 without a valid law, with and without trees."""
    model, full, _ = _case(name, n=5)
    rng = np.random.default_rng(11)
    rows = np.repeat(full, 60, axis=0)
    index = fw.VECTOR_FIELDS.index
    breaks = (np.nan, np.inf, -np.inf, 0.0, -1.0, 1.0, 2.0, 1.0 - 1e-7)
    for row in rows[5:]:  # the first rows stay valid
        for field in rng.choice(len(fw.VECTOR_FIELDS), rng.integers(1, 3), replace=False):
            row[field] = rng.choice(breaks)
    rows[5:40:7, index("height_cap")] = np.inf
    rows[5:40:14, index("apex_density")] = 0.0
    rows[40:80:3, index("cohort2_fraction")] = 0.3
    rows[40:80:5, index("cohort2_height_sd")] = -1.0
    family = HEIGHT_DISTRIBUTIONS[model.template.height_family]
    ok = assert_backends_agree(physical_rows, rows, family, model.template.height_truncation)
    assert ok[:5].all() and not ok.all()
