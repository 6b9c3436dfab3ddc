"""The compiled stand mapping against its numpy reference."""

import numpy as np
import pytest

from lidarinv.inference.model.parameters import DEFAULT_STRUCTURE_PRIORS
from lidarinv.inference.model.stand import StandMapping, default_template
from lidarinv.testing import assert_fast_path


def _rows(rng, n):
    v = {name: prior.sample(rng, n) for name, prior in DEFAULT_STRUCTURE_PRIORS.items()}
    v.update(rho_ratio=np.full(n, 1.5), ground_elevation=rng.normal(0.0, 1.0, n))
    # stands from the tallest and sparsest to ones cut at the ground (mean < 2 sd)
    v["top_height"][:3] = [1.2, 80.0, 3.0]
    v["height_sd"][:3] = [0.1, 10.0, 1.0]
    v["cover"][:3] = [0.001, 0.99, 0.5]
    return v


@pytest.mark.parametrize("shapes", [("cone", "ellipsoid"), ("hemi-ellipsoid", "cylinder")])
def test_compiled_mapping_equals_the_numpy_reference(shapes):
    """Every model-vector column and derived quantity, over prior draws and edge stands
    (sparse and dense, thin and wide height distributions, cut at the ground)."""
    mapping = StandMapping(default_template(shapes), shapes, backend="numba")
    assert mapping.backend == "numba"
    reference = StandMapping(default_template(shapes), shapes, backend="numpy")
    v = _rows(np.random.default_rng(6), 400)
    ok = mapping.valid(v)
    v = {name: values[ok] for name, values in v.items()}
    assert ok.sum() > 300 and ok[:3].all()
    ref_vectors, _ = assert_fast_path(mapping.model_vectors, reference.model_vectors, v, rtol=1e-10)
    np.testing.assert_allclose(mapping.model_vectors(v)[0], ref_vectors, rtol=1e-11, atol=0)


def test_only_truncated_normal_heights_take_the_compiled_path():
    template = default_template().with_values(height_family="weibull")
    assert StandMapping(template, backend="numba").backend == "numpy"
