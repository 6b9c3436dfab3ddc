import os

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import forward as fw
from lidarinv.inference.model.priors import LogUniform, TruncatedNormal, Uniform


def random_stand(rng, n=60, half_width=25.0, shapes=fw.SHAPE_NAMES, favd=0.8):
    height = rng.uniform(8.0, 30.0, n)
    return fw.Stand.from_arrays(
        x=rng.uniform(-half_width, half_width, n),
        y=rng.uniform(-half_width, half_width, n),
        height=height,
        crown_length=rng.uniform(0.3, 0.7, n) * height,
        crown_radius=rng.uniform(0.05, 0.13, n) * height,
        favd=favd,
        shape=rng.choice(list(shapes), n),
    )


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture
def gedi():
    return fw.instrument_preset("gedi")


@pytest.fixture
def nuisance_priors():
    """Shot-independent nuisance priors for building a default parameter space."""
    return {
        "ground_elevation": TruncatedNormal(0.0, 0.1, -1.0, 1.0),
        "gain": LogUniform(1.0, 100.0),
        "baseline": Uniform(-1.0, 1.0),
        "noise_sigma": LogUniform(0.1, 10.0),
    }


def pytest_collection_modifyitems(config, items):
    """The docs build (about a minute and a half) first: with two workers it then runs
    beside the rest of the suite instead of after it."""
    items.sort(key=lambda item: item.get_closest_marker("docs") is None)


#: One BLAS thread a process when the suite runs on several workers (and in the processes
#: they start: the docs build, the CLI, batch workers): each worker already has a core, and
#: BLAS threads waiting for a busy core made small-matrix tests ten times slower.
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def pytest_configure(config):
    if hasattr(config, "workerinput"):  # a pytest-xdist worker
        for name, value in ONE_THREAD.items():
            os.environ.setdefault(name, value)
        threadpool_limits(1)
