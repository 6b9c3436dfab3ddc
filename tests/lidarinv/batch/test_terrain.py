"""Terrain context in a batch over a file: a shot whose ground leaves its track
neighbours' is flagged, as ``lidarinv metrics`` flags it, and the option of a ground prior
from the terrain fit gives the inversion that prior."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from lidarinv.batch.store import group_name
from lidarinv.batch.terrain import WithTerrain, terrain_context
from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference.model.priors import TruncatedNormal
from lidarinv.observe.terrain import TERRAIN_FLAG

SLOPE = 0.02  # terrain rising 2 m per 100 m along the track
SPACING_M = 40.0
LIFTED = 6  # the shot whose analysed ground sits on a layer 15 m up


@pytest.fixture(scope="module")
def track():
    shot = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(7))
    shots = []
    for i in range(14):
        along = i * SPACING_M
        lift = 15.0 if i == LIFTED else 0.0
        metadata = {"latitude": along / 111_195.0, "longitude": 0.0, "beam": "BEAM0000"}
        shots.append(
            replace(shot, shot_id=i, axis=shot.axis + SLOPE * along + lift, metadata=metadata)
        )
    return shots


def test_the_shot_that_leaves_its_neighbours_is_flagged(track):
    context = terrain_context(None, track, instrument="gedi")
    assert list(context.flags) == [group_name(LIFTED)]  # keyed as the results file is
    assert context.flags[group_name(LIFTED)].startswith(TERRAIN_FLAG)
    expected, sigma = context.expected[group_name(LIFTED)]
    assert expected == pytest.approx(SLOPE * LIFTED * SPACING_M, abs=1.0)
    assert 0.0 < sigma < 1.0


def _recording_invert(calls):
    def invert(observation, settings=None, *, rng=None, progress=False):
        calls.append(settings)
        return SimpleNamespace(flags=[])

    return invert


def test_results_carry_the_flag_and_the_option_takes_the_terrain_prior(track):
    context = terrain_context(None, track, instrument="gedi")
    calls = []
    plain = WithTerrain(_recording_invert(calls), context)
    assert plain(track[LIFTED]).flags[0].startswith(TERRAIN_FLAG)
    assert plain(track[0]).flags == [] and calls == [None, None]  # shots stay independent
    with_prior = WithTerrain(_recording_invert(calls), context, ground_prior=True)
    with_prior(track[LIFTED])
    prior = calls[-1].priors["ground_elevation"]["prior"]
    assert isinstance(prior, TruncatedNormal)
    assert prior.mean == pytest.approx(SLOPE * LIFTED * SPACING_M, abs=1.0)
