"""A canopy height that a bare footprint cannot inflate: the probability that the footprint
holds no tree, from the Poisson stand's density and the footprint's disc, and the height
given that it holds one."""

import numpy as np
import pytest
from scipy.special import ndtr
from tiny_results import tiny_result

from forward.pulse import GaussianPulse
from lidarinv.cli.invert import headline
from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
from lidarinv.inference import InversionSettings, build_problem, invert_shot
from lidarinv.inference.model.tallest_stem import disc_area
from lidarinv.inference.results.collect import footprint_top_height
from lidarinv.inference.results.flags import is_warning
from lidarinv.inference.results.footprint import (
    UNSEEN_TOP_NOTE,
    BareGround,
    canopy_height_note,
    footprint_no_stem,
    stand_rh98_note,
    unseen_top_note,
)
from lidarinv.inference.sampling import SamplerSettings
from lidarinv.observe.observation import Observation


@pytest.fixture(scope="module")
def problem():
    shot = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(3))
    return build_problem(shot, InversionSettings(cohorts=1)), shot


def test_no_stem_probability_is_the_share_of_footprints_without_a_stem(problem):
    """Draws of the footprint's tallest stem are 0 (no stem in the disc) as often as a
    Poisson count of mean λ·A is 0."""
    problem, shot = problem
    truth = np.array([shot.truth[name] for name in problem.space.names])
    x = np.repeat(truth[None, :], 20000, axis=0)
    area = disc_area(problem.instrument.footprint_sigma_m)
    density_per_ha = np.full(x.shape[0], 0.7 / area * 1e4)  # 0.7 stems a footprint
    no_stem = footprint_no_stem(problem, density_per_ha)
    np.testing.assert_allclose(no_stem, np.exp(-0.7))
    tallest = footprint_top_height(problem, x, density_per_ha, np.random.default_rng(1))
    assert np.mean(tallest == 0.0) == pytest.approx(np.exp(-0.7), abs=0.01)
    assert np.all(tallest[tallest > 0] > 1.0)  # a stem that stands has a height


def test_a_bare_ground_return_reaches_its_pulse_s_98_percent_quantile():
    """A flat ground under a Gaussian pulse of σp widened by σb returns a Gaussian of
    σ = √(σp² + σb²): 98 % of it lies below 2.054 σ above its peak (plus the RH's bin)."""
    pulse = GaussianPulse(10.0)
    sigma_p = pulse.sigma_m
    broadening = np.array([0.0, 0.5, 1.5])
    expected = 2.0537 * np.hypot(sigma_p, broadening) + 0.15
    rh98 = BareGround(pulse, broadening).rh98(broadening, 0.15)
    np.testing.assert_allclose(rh98, expected, atol=0.02)


def test_a_bare_ground_table_gives_each_broadening_its_widened_gaussian():
    """One table spanning the broadenings of many samples gives each sample's bare ground
    the cumulative fraction of a Gaussian of σ = √(σp² + σb²) about its peak, and the
    RH98 that a table made for that sample alone gives."""
    pulse = GaussianPulse(10.0)
    broadening = np.linspace(0.0, 2.0, 200)
    table = BareGround(pulse, broadening)
    offsets = np.tile(np.linspace(-3.0, 3.0, 13), (broadening.size, 1))
    sigma = np.hypot(pulse.sigma_m, broadening)[:, None]
    np.testing.assert_allclose(table.cdf(broadening, offsets), ndtr(offsets / sigma), atol=0.01)
    alone = [BareGround(pulse, [b]).rh98([b], 0.15)[0] for b in broadening[::40]]
    np.testing.assert_allclose(table.rh98(broadening[::40], 0.15), alone, atol=0.01)
    assert np.isnan(table.rh98([np.nan], 0.15)[0])


def _bare(p_stem, seed=0, p_bare=None):
    """A tiny result whose footprint holds a 9 m stem with probability ``p_stem``."""
    result = tiny_result(seed=seed)
    rng = np.random.default_rng(seed)
    n = result.samples.shape[0]
    standing = rng.uniform(size=n) < p_stem
    result.derived["footprint_top_height"] = np.where(standing, rng.normal(9.3, 0.5, n), 0.0)
    result.derived["footprint_no_stem_probability"] = np.full(n, 1.0 - p_stem)
    result.units.update(footprint_top_height="m", footprint_no_stem_probability="1")
    if p_bare is not None:
        result.derived["footprint_bare"] = (rng.uniform(size=n) < p_bare).astype(float)
    return result


def test_a_bare_footprint_says_so_and_keeps_the_height_of_a_tree_apart():
    canopy = _bare(0.2).footprint_canopy()
    assert canopy["no_tree_probability"] == pytest.approx(0.8)
    given = canopy["height_given_canopy"]
    assert 8.0 < given["p05"] < given["median"] < given["p95"] < 10.5
    text = headline(_bare(0.2))
    assert "more likely holds no tree" in text and "canopy height if any" in text
    assert "more likely holds no tree" not in headline(_bare(0.9))
    row = _bare(0.2).summary_row()
    assert row["footprint_no_tree_probability"] == pytest.approx(0.8)
    assert row["footprint_height_given_canopy_median"] == pytest.approx(given["median"])


def test_a_footprint_whose_waveform_shows_no_canopy_says_so():
    """Many small stems (no tree is unlikely) whose crowns return nothing above the ground:
    the headline says the waveform sees no canopy."""
    text = headline(_bare(0.99, p_bare=0.9))
    assert "more likely holds no tree" not in text
    assert "more likely holds no canopy the waveform sees" in text
    assert _bare(0.99, p_bare=0.9).footprint_canopy()["bare_probability"] == pytest.approx(
        0.9, abs=0.05
    )
    assert "no canopy the waveform sees" not in headline(_bare(0.99, p_bare=0.1))


def test_a_result_without_the_quantity_has_no_canopy_statement():
    assert tiny_result().footprint_canopy() is None
    assert "P(no tree" not in headline(tiny_result())


def _gedi_like_shot(canopy_dn, rng, broadening_m=1.0):
    """A shot with its own Gaussian transmitted pulse (σ 6.6 ns, about 1 m) whose ground
    returns the pulse widened by ``broadening_m`` (150 DN high), and a low canopy's return
    ``canopy_dn`` high about 3 m above it, under 1.5 DN of white noise."""
    t = np.arange(128.0)
    transmitted = 10.0 + 200.0 * np.exp(-0.5 * ((t - 40.0) / 6.6) ** 2)
    transmitted += rng.normal(0.0, 0.5, t.size)
    axis = np.arange(-15.0, 25.0, 0.15)
    ground_sigma = np.hypot(6.6 * 0.15, broadening_m)
    clean = 150.0 * np.exp(-0.5 * (axis / ground_sigma) ** 2)
    clean += canopy_dn * np.exp(-0.5 * ((axis - 3.0) / 1.0) ** 2)
    samples = 50.0 + clean + rng.normal(0.0, 1.5, axis.size)
    return Observation(
        samples=samples, axis=axis, shot_id="bare", pulse=transmitted, pulse_ns=1.0,
        instrument="gedi",
    )  # fmt: skip


@pytest.fixture(scope="module")
def quick_settings():
    quick = SamplerSettings(
        n_walkers=16, max_steps=200, check_every=100, candidates=256, starts=4, polish=1,
        fit_steps=(100,),
    )  # fmt: skip
    return InversionSettings(cohorts=1, discrepancy_model="observed", sampler=quick)


def test_a_bare_ground_with_a_widened_return_holds_no_canopy(quick_settings):
    """A ground return twice as wide as the pulse and nothing above it: the waveform shows
    no canopy, and the headline height is the zero of a bare footprint, not the top of a
    stand of stems whose crowns the noise hides."""
    shot = _gedi_like_shot(0.0, np.random.default_rng(1))
    result = invert_shot(shot, quick_settings, rng=np.random.default_rng(0))
    canopy = result.footprint_canopy()
    assert canopy["bare_probability"] > 0.6
    assert canopy["none_probability"] >= canopy["bare_probability"]
    assert canopy["height"]["median"] == 0.0
    text = headline(result)
    assert "the footprint more likely holds no canopy" in text
    assert text.splitlines()[1].split()[:3] == ["canopy", "height", "0"]


def test_a_low_canopy_above_a_widened_ground_is_seen(quick_settings):
    """A canopy return a tenth of the ground's, 3 m above it: the waveform shows it."""
    shot = _gedi_like_shot(15.0, np.random.default_rng(1))
    result = invert_shot(shot, quick_settings, rng=np.random.default_rng(0))
    canopy = result.footprint_canopy()
    assert canopy["bare_probability"] < 0.1
    assert canopy["height"]["median"] > 2.0
    assert "more likely holds no canopy" not in headline(result)


def test_the_headline_height_is_zero_where_the_waveform_sees_no_canopy():
    """Stems in every draw, but a waveform that shows none in 90 % of them: the canopy
    height is 0 there, and the height given a canopy keeps the stems it sees."""
    result = _bare(0.99, p_bare=0.9)
    canopy = result.footprint_canopy()
    seen = (result.derived["footprint_bare"] == 0) & (result.derived["footprint_top_height"] > 0)
    assert canopy["none_probability"] == pytest.approx(1.0 - np.mean(seen))
    assert canopy["height"]["median"] == 0.0 and canopy["height"]["p95"] > 8.0
    assert 8.0 < canopy["height_given_canopy"]["median"] < 10.5
    row = result.summary_row()
    assert row["footprint_no_canopy_probability"] == pytest.approx(canopy["none_probability"])
    assert row["footprint_height_median"] == 0.0
    assert headline(result).splitlines()[1].split()[:3] == ["canopy", "height", "0"]


def test_a_sparse_tall_storey_missing_from_the_disc_is_flagged():
    """Half a tall stem a disc over many short ones: most draws of the disc's tallest stem
    are short while every draw's waveform shows the tall crowns (RH98 44 m): the canopy
    height contradicts the waveform, and the result says so. A stand whose tallest stem
    sits near its waveform's RH98, and a bare footprint, are not flagged."""
    rng = np.random.default_rng(0)
    n = 4000
    tall_in_disc = rng.poisson(0.5, n) > 0
    tallest = np.where(tall_in_disc, rng.normal(45.0, 1.0, n), rng.normal(10.0, 0.7, n))
    rh98 = rng.normal(44.0, 0.5, n)
    note = canopy_height_note(tallest, rh98, tolerance_m=2.3)
    assert note is not None and "61% of draws" in note and "rh98_footprint" in note
    one_storey = rng.normal(44.5, 1.0, n)
    assert canopy_height_note(one_storey, rh98, tolerance_m=2.3) is None
    bare = np.zeros(n)  # no canopy seen: RH98 is the bare ground's, a pulse high
    assert canopy_height_note(bare, np.full(n, 1.2), tolerance_m=2.3) is None
    assert canopy_height_note(np.full(n, np.nan), rh98, tolerance_m=2.3) is None
    # a waveform judged bare under a broadened ground: RH98 5 m up, nothing a bare ground
    # could not return, and no stem the canopy height counts
    judged_bare = rng.uniform(size=n) < 0.8
    broadened = np.full(n, 5.3)
    no_stem = np.where(judged_bare, 0.0, 5.0)
    assert canopy_height_note(no_stem, broadened, 2.3) is not None  # without the judgement
    assert canopy_height_note(no_stem, broadened, 2.3, bare=judged_bare) is None


def test_a_stand_whose_rh98_falls_below_the_footprints_is_flagged():
    """Draws whose expected stand's RH98 lies 8 m under their footprint waveform's (the
    discrepancy carrying a sparse top) are flagged; draws within a pulse width of it, above
    it, without a footprint RH98 (NaN), judged bare, or low in under half the draws are
    not."""
    rng = np.random.default_rng(4)
    n = 2000
    footprint = rng.normal(33.0, 0.5, n)
    low = footprint - rng.normal(8.0, 1.0, n)
    note = stand_rh98_note(low, footprint, tolerance_m=2.1)
    assert note is not None and "100% of draws" in note and "rh98_footprint" in note
    assert stand_rh98_note(footprint - 1.5, footprint, 2.1) is None
    assert stand_rh98_note(footprint + 3.0, footprint, 2.1) is None
    assert stand_rh98_note(low, np.full(n, np.nan), 2.1) is None
    assert stand_rh98_note(low, footprint, 2.1, bare=np.ones(n)) is None
    some = np.where(rng.uniform(size=n) < 0.4, low, footprint)
    assert stand_rh98_note(some, footprint, 2.1) is None


def test_a_stem_above_every_recorded_return_is_noted():
    """Draws whose tallest stem stands 8 m above the waveform's signal start get the note
    (not a warning); stems under the signal start, within a pulse width above it, on a
    bare disc (0 m), or above it in under half the draws do not."""
    rng = np.random.default_rng(3)
    n = 2000
    signal_top = rng.normal(43.0, 0.3, n)  # the signal start above each draw's ground
    unseen = rng.normal(51.0, 1.0, n)
    note = unseen_top_note(unseen, signal_top, tolerance_m=2.3)
    assert note is not None and note.startswith(UNSEEN_TOP_NOTE) and "100% of draws" in note
    assert not is_warning(note)
    assert unseen_top_note(rng.normal(41.0, 1.0, n), signal_top, 2.3) is None
    assert unseen_top_note(signal_top + 1.5, signal_top, 2.3) is None  # the pulse's spread
    assert unseen_top_note(np.zeros(n), signal_top, 2.3) is None
    half = np.where(rng.uniform(size=n) < 0.4, unseen, 40.0)  # 40 % above: not most
    assert unseen_top_note(half, signal_top, 2.3) is None
