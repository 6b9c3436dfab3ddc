"""A misfit the model error cannot hide: with the ground held on the canopy (the failure of
a closed canopy's analysis), the model leaves the ground's return and the crowns below
unexplained; their residuals need more model error than the instrument model may lack, so
the likelihood keeps the ceiling and the shot is flagged a misfit. The shot with its
ground free is not."""

from dataclasses import replace

import numpy as np
import pytest

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, SamplerSettings
from lidarinv.inference.invert import prepare_problem
from lidarinv.inference.passes.model_error import MISFIT_FLAG, MODEL_ERROR_CEILING
from lidarinv.inference.settings import RealisationSettings

SETTINGS = InversionSettings(
    cohorts=1,
    realisations=RealisationSettings(count=8),
    sampler=SamplerSettings(candidates=64, starts=2),
)


@pytest.fixture(scope="module")
def shot():
    return synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(11))


def _misfits(prepared):
    return [note for note in prepared.notes if note.startswith(MISFIT_FLAG)]


def test_a_fit_needing_more_than_the_ceiling_is_flagged_a_misfit(shot):
    on_canopy = shot.truth["ground_elevation"] + 0.5 * shot.truth["top_height"]
    settings = replace(SETTINGS, priors={"ground_elevation": {"fixed": on_canopy}})
    prepared = prepare_problem(shot, settings, np.random.default_rng(5))
    found = prepared.diagnostics()
    assert found["model_error_needed"] > MODEL_ERROR_CEILING
    assert found["instrument_floor"] == MODEL_ERROR_CEILING
    assert found["model_error_ceiling"] == MODEL_ERROR_CEILING
    assert _misfits(prepared)


def test_the_shot_with_its_ground_free_is_not_a_misfit(shot):
    prepared = prepare_problem(shot, SETTINGS, np.random.default_rng(5))
    assert prepared.diagnostics()["model_error_needed"] <= MODEL_ERROR_CEILING
    assert not _misfits(prepared)
