"""How many realisations a shot's discrepancy simulates: the first share where the spread
they leave is small enough, all of them where it is not, the same stands either way."""

import numpy as np
import pytest

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, SamplerSettings, invert_shot
from lidarinv.inference.invert import prepare_problem
from lidarinv.inference.results import realisation_spread as spread_module
from lidarinv.inference.settings import RealisationSettings

QUICK = SamplerSettings(candidates=64, starts=2, polish=1)


@pytest.fixture(scope="module")
def shot():
    return synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(11))


def _prepared(shot, target):
    realisations = RealisationSettings(count=16, first_fraction=0.25, spread_target=target,
                                       resamples=4)  # fmt: skip
    settings = InversionSettings(realisations=realisations, sampler=QUICK, cohorts=1)
    return prepare_problem(shot, settings, np.random.default_rng(5))


def test_the_first_realisations_suffice_only_where_their_spread_is_within_the_target(shot):
    """A target no spread exceeds keeps the first quarter; a target of 0 simulates all
    16. The first four stands are the same in both (a stream each), and the record says
    how many were asked, simulated, and the spread that decided."""
    few, every = _prepared(shot, np.inf), _prepared(shot, 0.0)
    assert few.discrepancy_draws.residuals.shape[0] == 4
    assert every.discrepancy_draws.residuals.shape[0] == 16
    np.testing.assert_array_equal(
        few.discrepancy_draws.residuals, every.discrepancy_draws.residuals[:4]
    )
    for prepared, simulated in ((few, 4), (every, 16)):
        record = prepared.diagnostics()["realisations"]
        assert record["asked"] == 16 and record["simulated"] == simulated
        assert record["first_spread"] > 0.0


def test_a_large_spread_after_sampling_says_the_first_realisations_were_too_few(shot, monkeypatch):
    """Where the first realisations seemed enough before sampling but the spread measured
    after it is flagged, the flag asks for all of them, not for a larger count."""
    monkeypatch.setattr(spread_module, "FLAG_SPREAD_SD", 0.0)  # every spread is too large
    realisations = RealisationSettings(count=16, spread_target=np.inf, resamples=4)
    quick = SamplerSettings(max_steps=100, check_every=100, candidates=64, starts=2, polish=1)
    settings = InversionSettings(realisations=realisations, sampler=quick, cohorts=1)
    result = invert_shot(shot, settings, rng=np.random.default_rng(2))
    flag = next(f for f in result.flags if f.startswith(spread_module.SEED_SPREAD_NOTE))
    assert "the first 4 of 16" in flag and "first_fraction = 1" in flag


def test_the_first_count_is_a_share_of_the_count_and_settings_are_checked():
    assert RealisationSettings(count=256).first_count == 64
    assert RealisationSettings(count=3, first_fraction=0.1).first_count == 2
    assert RealisationSettings(count=8, first_fraction=1.0).first_count == 8
    with pytest.raises(ValueError, match="first_fraction"):
        RealisationSettings(first_fraction=0.0)
    with pytest.raises(ValueError, match="spread_target"):
        RealisationSettings(spread_target=-1.0)
