"""Weak ground returns under a closed canopy: windowed energy against correlated noise."""

import numpy as np
import pytest
from closed_canopy import GROUND_Z, LVIS_NOISE_FILTER, closed_canopy, closed_canopy_shot

from lidarinv.observe import analyse, estimate_noise
from lidarinv.observe.ground_candidates import (
    CONFIDENT_FALSE_ALARM,
    GroundCandidate,
    choose_ground,
    rescaled_level,
    significance_sigmas,
    window_sum_sigma,
)


def test_the_stand_is_closed_and_the_noise_lvis_like():
    _, waveform = closed_canopy()
    assert waveform.ground_gap <= 0.03  # cover ≥ 0.97
    assert waveform.ground_energy < 0.02 * waveform.canopy_energy
    result = analyse(closed_canopy_shot(0))
    assert result.noise.autocorrelation[1:4] == pytest.approx([0.60, 0.31, 0.11], abs=0.1)


def test_weak_ground_under_a_closed_canopy_is_found_or_flagged():
    """The ground return, 1/50 of the canopy's energy and no prominent mode, is the
    ground, or the shot is flagged ambiguous with the true ground as the alternative."""
    canopy_taken = 0
    for seed in range(8):
        result = analyse(closed_canopy_shot(seed))
        assert result.ok, result.reason
        if abs(result.ground - GROUND_Z) > 0.5:
            assert "ground ambiguous" in result.flags
            assert result.ground_alternative == pytest.approx(GROUND_Z, abs=0.5)
        # the lowest prominent mode lies in the canopy: the weak return decided
        canopy_taken += result.ground_alternative > GROUND_Z + 10.0
    assert canopy_taken >= 4


def test_window_sum_sigma_follows_the_measured_autocorrelation():
    rng = np.random.default_rng(5)
    filt = np.asarray(LVIS_NOISE_FILTER)
    white = rng.standard_normal(200_000 + filt.size - 1)
    noise = np.convolve(white, filt / np.sqrt(np.sum(filt**2)), mode="valid") * 1.9
    model = estimate_noise(noise[:4000], np.ones(4000, bool), max_lag=16)
    for width in (3, 9, 15):
        sums = np.convolve(noise, np.ones(width), mode="valid")[::width]
        assert window_sum_sigma(model, width) == pytest.approx(np.std(sums), rel=0.08)
    # white-noise arithmetic (σ√n) would understate it by a factor √(Σ R) ≈ 1.7
    assert window_sum_sigma(model, 9) > 1.5 * 1.9 * 3


def test_significance_level_grows_with_the_windows_searched():
    assert significance_sigmas(1, 0.01) == pytest.approx(2.326, abs=1e-3)
    assert significance_sigmas(30, 0.01) > significance_sigmas(3, 0.01) > 2.326


def _candidate(z, kind="mode", energy=20.0, separation=10.0):
    return GroundCandidate(z, z, kind, energy, separation)


def test_lowest_significant_candidate_is_chosen():
    choice = choose_ground([_candidate(1.0), _candidate(5.0), _candidate(9.0)], 3.3, 2.7)
    assert choice.chosen.position == 1.0 and not choice.ambiguous
    assert choice.alternative.position == 9.0  # the lowest prominent mode, reported


def test_rescaled_level_is_the_same_search_at_another_false_alarm():
    for trials in (1, 12, 80):
        level = significance_sigmas(trials)
        assert rescaled_level(level, CONFIDENT_FALSE_ALARM) == pytest.approx(
            significance_sigmas(trials, CONFIDENT_FALSE_ALARM), rel=1e-9
        )


def test_barely_significant_return_below_the_mode_keeps_the_mode_plausible():
    """A return that passes the 1 % level by a hair is as likely a noise excursion as a
    ground: the lowest mode stays the alternative and the choice is ambiguous; one that
    passes the 0.1 % level is chosen outright."""
    level = 3.3
    confident = rescaled_level(level, CONFIDENT_FALSE_ALARM)
    assert confident > level + 0.5
    for energy, ambiguous in ((level + 0.1, True), (confident + 0.1, False)):
        choice = choose_ground([_candidate(1.0, energy=energy), _candidate(9.0)], level, 2.7)
        assert choice.chosen.position == 1.0
        assert choice.alternative.position == 9.0
        assert choice.ambiguous is ambiguous


def test_shoulder_below_a_weaker_mode_leaves_the_choice_ambiguous():
    candidates = [_candidate(1.0, "shoulder"), _candidate(5.0, energy=8.0), _candidate(9.0)]
    choice = choose_ground(candidates, 3.3, 2.7)
    assert choice.chosen.position == 5.0 and choice.ambiguous
    assert choice.alternative.position == 1.0


def test_marginal_return_below_is_the_alternative():
    candidates = [_candidate(1.0, energy=3.0), _candidate(5.0), _candidate(9.0)]
    choice = choose_ground(candidates, 3.3, 2.7)
    assert choice.chosen.position == 5.0 and choice.ambiguous
    assert choice.alternative.position == 1.0


def test_modes_only_rule_ignores_shoulders():
    candidates = [_candidate(1.0, "shoulder"), _candidate(9.0)]
    choice = choose_ground(candidates, 3.3, 2.7, kinds=("mode",))
    assert choice.chosen.position == 9.0 and choice.alternative is None
