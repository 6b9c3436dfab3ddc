"""Weak ground returns under a closed canopy: windowed energy against correlated noise."""

import numpy as np
import pytest

import forward as fw
from lidarinv.observe import analyse, estimate_noise, observe
from lidarinv.observe.ground_candidates import (
    GroundCandidate,
    choose_ground,
    significance_sigmas,
    window_sum_sigma,
)

#: A digitiser noise filter whose autocorrelation is LVIS's measured one
#: (R(1), R(2), R(3) ≈ 0.60, 0.31, 0.11 on the Mondah waveforms' signal-free bins).
LVIS_NOISE_FILTER = [1.0, 0.858, 3.257, 1.661]
GROUND_Z = 100.0  # m


@pytest.fixture(scope="module")
def closed_canopy():
    """A tall (30–45 m), dense two-storey stand over one LVIS footprint: ground gap ≤ 0.03."""
    inst = fw.instrument_preset("lvis")
    rng = np.random.default_rng(3)
    grid = np.arange(-16, 16.1, 3.2)
    x, y = (a.ravel() + rng.uniform(-0.8, 0.8, a.size) for a in np.meshgrid(grid, grid))
    n, m = x.size, 60
    stand = fw.Stand.from_arrays(
        x=np.r_[x, rng.uniform(-16, 16, m)],
        y=np.r_[y, rng.uniform(-16, 16, m)],
        height=np.r_[rng.uniform(30, 45, n), rng.uniform(11, 20, m)],
        crown_length=np.r_[rng.uniform(10, 18, n), rng.uniform(4, 10, m)],
        crown_radius=np.r_[rng.uniform(2.5, 3.5, n), rng.uniform(1.0, 2.0, m)],
        favd=0.4,
        shape="ellipsoid",
    )
    heights = np.arange(-20, 60, inst.bin_height)
    waveform = fw.WaveformSimulator(inst).simulate(stand, heights=heights)
    return inst, waveform


def _shot(closed_canopy, seed, gain=30000.0):
    inst, waveform = closed_canopy
    return observe(waveform, gain=gain, baseline=64.0, noise_sigma=1.9, quantise=True,
                   rng=np.random.default_rng(seed), noise_filter=LVIS_NOISE_FILTER,
                   instrument=inst, ground_elevation=GROUND_Z)  # fmt: skip


def test_the_stand_is_closed_and_the_noise_lvis_like(closed_canopy):
    _, waveform = closed_canopy
    assert waveform.ground_gap <= 0.03  # cover ≥ 0.97
    assert waveform.ground_energy < 0.02 * waveform.canopy_energy
    result = analyse(_shot(closed_canopy, 0))
    assert result.noise.autocorrelation[1:4] == pytest.approx([0.60, 0.31, 0.11], abs=0.1)


def test_weak_ground_under_a_closed_canopy_is_found_or_flagged(closed_canopy):
    """The ground return, 1/50 of the canopy's energy and no prominent mode, is the
    ground, or the shot is flagged ambiguous with the true ground as the alternative."""
    canopy_taken = 0
    for seed in range(8):
        result = analyse(_shot(closed_canopy, seed))
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
