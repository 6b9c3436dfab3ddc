"""Inversions of real shots shipped with the package (GEDI cerrado, LVIS Gabon).

The shots are picked by what their own analysis says (a single mode; the most modes),
never by identifier. Short chains under the observed-signal discrepancy keep these
tests to seconds; the full comparison with the products is ``studies/real_inversion.py``.
"""

from dataclasses import replace

import numpy as np
import pytest

from lidarinv.inference import InversionSettings, invert_shot
from lidarinv.inference.sampling import ImportanceSettings
from lidarinv.io import example_file, iter_observations
from lidarinv.observe import processing_settings
from lidarinv.observe.analyse import analyse

SHORT = InversionSettings(discrepancy_model="observed")
SHORT = replace(SHORT, sampler=replace(SHORT.sampler, max_steps=400))


def _analysed(name):
    shots = [(obs, analyse(obs)) for obs in iter_observations(example_file(name))]
    return [(obs, a) for obs, a in shots if a.status == "ok" and not a.flags]


def test_a_single_peak_real_shot_puts_the_ground_at_the_peak_under_a_low_canopy():
    single = [(obs, a) for obs, a in _analysed("gedi-l1b") if a.n_modes == 1]
    obs, analysis = min(single, key=lambda pair: pair[1].rh[98])
    result = invert_shot(obs, SHORT, rng=np.random.default_rng(3))
    ground = np.median(result.column("ground_elevation"))
    assert abs(ground - analysis.ground) < 0.3
    rh98 = np.percentile(result.column("rh98"), [5, 95])
    assert rh98[1] < 10.0  # a low canopy, not the ground return read as a tall one
    assert np.median(result.column("gap_cover")) < 0.6
    # every sampled parameter is set against its prior; the ground peak pins the ground
    learning = result.diagnostics["prior_learning"]
    assert set(learning) == set(result.diagnostics["sampled"])
    assert "ground_elevation" not in result.prior_dominated
    assert learning["ground_elevation"]["contraction"] > 0.3
    assert result.diagnostics["importance_tries"][0][0] == 200  # tried, and judged


def test_importance_draws_that_pass_are_the_result_and_it_says_so():
    """A one-layer posterior close to a t: under a lower ESS asked of them than the
    default, the first try's weighted draws end the run, and the result is made of them,
    with the weights' k̂ and every quantity's ESS from them, and no τ."""
    single = [(obs, a) for obs, a in _analysed("gedi-l1b") if a.n_modes == 1]
    obs, _ = min(single, key=lambda pair: pair[1].rh[98])
    lenient = ImportanceSettings(ess_min=400.0, quantile_mcse_max=1.0)
    settings = replace(SHORT, sampler=replace(SHORT.sampler, importance=lenient))
    result = invert_shot(obs, settings, rng=np.random.default_rng(3))
    d = result.diagnostics
    assert d["sampling"] == "importance" and d["n_steps"] == d["importance"]["step"] == 200
    assert d["importance"]["khat"] <= 0.5 and result.samples.shape[0] == 4096
    assert all(min(q["ess_bulk"], q["ess_tail"]) >= 400 for q in d["quantities"].values())
    table = result.summary_table()
    assert "importance sampling" in table and "max τ" not in table


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_a_two_layer_real_shot_is_fitted_with_two_cohorts_when_they_are_available():
    obs, analysis = max(_analysed("lvis-l1b"), key=lambda pair: pair[1].n_modes)
    result = invert_shot(obs, replace(SHORT, cohorts="auto"), rng=np.random.default_rng(4))
    choice = result.diagnostics["cohorts"]
    assert choice["chosen"] == 2
    assert choice["bic"][2] < choice["bic"][1] - 10.0 and not choice["undecided"]
    assert result.settings["cohorts"] == 2
    assert "cohort2_fraction" in result.parameter_names
    # in LVIS L2's convention (recorded counts) the posterior RH98 is the shot's own
    product_rh98 = np.median(result.column("rh98_product"))
    assert abs(product_rh98 - analysis.rh[98]) < 1.0
    # the footprint's own waveform (the fitted one and the discrepancy the data show) has
    # the RH98 of the shot's waveform in the model's convention (energy above the noise)
    convention = replace(processing_settings("lvis"), rh_energy="above-noise", rh_smoothed=False)
    own = analyse(obs, convention).rh[98]
    footprint = np.percentile(result.column("rh98_footprint"), [5, 50, 95])
    assert footprint[0] - 0.5 <= own <= footprint[2] + 0.5


def test_the_real_inversion_study_counts_storeys_chosen_by_strong_evidence():
    """Two storeys chosen with a BIC lower by 50 and by 5, one storey where two were not
    searched: two shots with two cohorts, one of them by more than 10."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[3] / "studies" / "real_inversion.py"
    spec = importlib.util.spec_from_file_location("real_inversion_study", path)
    study = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(study)

    def record(cohorts, gain):
        return {"instrument": "lvis", "shot": 1, "posterior": {}, "converged": True,
                "flags": [], "seconds": 1.0, "cohorts": cohorts, "bic_two_cohorts_gain": gain}  # fmt: skip

    records = [record(2, 50.0), record(2, 5.0), record(1, np.nan), {**record(1, 0.0)}]
    del records[-1]["bic_two_cohorts_gain"]  # a run from before the count
    out = study.statistics(records, "lvis")
    assert (out["two_cohorts"], out["two_cohorts_bic_over_10"]) == (2, 1)
    assert study.statistics(records[-1:], "lvis")["two_cohorts_bic_over_10"] is None
