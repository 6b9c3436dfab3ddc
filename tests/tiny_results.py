"""A small, complete InversionResult built without sampling, for CLI and figure tests."""

import numpy as np

from lidarinv.inference import InversionResult


def tiny_result(shot_id="gedi-mixed", seed=0):
    """A small but complete InversionResult (no sampling)."""
    rng = np.random.default_rng(seed)
    names = ("cover", "top_height", "gain")
    samples = np.column_stack(
        [rng.uniform(0.4, 0.6, 200), rng.normal(20, 1, 200), rng.normal(100, 5, 200)]
    )
    axis = np.linspace(-5, 30, 60)
    observed = 10 + rng.normal(0, 1, 60)
    band = np.tile(observed, (5, 1)) + np.array([-2, -1, 0, 1, 2])[:, None]
    return InversionResult(
        shot_id=shot_id,
        parameter_names=names,
        units={"cover": "1", "top_height": "m", "gain": "DN", "rh98": "m", "gap_cover": "1"},
        samples=samples,
        log_prob=rng.normal(size=200),
        derived={
            "rh98": rng.normal(15, 1, 200),
            "footprint_top_height": rng.normal(18, 1, 200),
            "gap_cover": rng.uniform(0.3, 0.5, 200),
        },
        fixed={"crown_radius_slope": 0.1, "rho_ratio": None},
        diagnostics={
            "tau": np.ones(3),
            "acceptance": np.full(4, 0.3),
            "ess": np.full(3, 100.0),
            "n_steps": 100,
            "n_walkers": 4,
            "converged": True,
        },
        flags=[],
        profile_heights=np.linspace(0, 20, 10),
        profile=np.ones((5, 10)),
        axis=axis,
        observed=observed,
        censored=np.zeros(60, bool),
        predictive=band,
        noise_floor=12.0,
        priors=[],
        settings={},
    )
