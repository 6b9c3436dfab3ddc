"""The recovery study's calibration summary (``studies/recovery.py``) on shots with known
posteriors."""

import json

import numpy as np
import pytest
from scipy import stats


@pytest.fixture(scope="module")
def recovery():
    import recovery  # studies/recovery.py (pyproject's pythonpath)

    return recovery


def gaussian_rows(rng, n, width_factor):
    """Shots whose truth is drawn from N(centre, 1) and whose reported posterior is
    N(centre, width_factor²)."""
    probabilities = {"p05": 0.05, "p16": 0.16, "median": 0.5, "p84": 0.84, "p95": 0.95}
    rows = []
    for centre in rng.normal(0.0, 5.0, n):
        posterior = {k: centre + width_factor * stats.norm.ppf(p) for k, p in probabilities.items()}
        rows.append({"truth": {"cover": centre + rng.normal()}, "posterior": {"cover": posterior}})
    return rows


def test_calibrated_intervals_give_unit_spread_and_five_percent_tails(recovery):
    rows = gaussian_rows(np.random.default_rng(1), 4000, 1.0)
    out = recovery.calibration_of(rows, "cover")
    assert abs(out["z_median"]) < 0.05
    assert out["z_spread"] == pytest.approx(1.0, abs=0.05)
    assert out["below_p05"] == pytest.approx(0.05, abs=0.012)
    assert out["above_p95"] == pytest.approx(0.05, abs=0.012)


def test_intervals_twice_too_wide_halve_the_spread(recovery):
    rows = gaussian_rows(np.random.default_rng(2), 4000, 2.0)
    out = recovery.calibration_of(rows, "cover")
    assert out["z_spread"] == pytest.approx(0.5, abs=0.03)
    assert out["below_p05"] + out["above_p95"] < 0.01


def test_truth_drawn_from_the_priors_in_effect(recovery, tmp_path):
    from lidarinv.inference import InversionSettings

    path = tmp_path / "priors.toml"
    path.write_text(
        '[top_height]\nkind = "uniform"\nlower = 12.0\nupper = 20.0\n'
        "[understory_lai]\nfixed = 0.0\n[favd]\nlower = 0.3\nupper = 1.2\n"
    )
    settings = InversionSettings.from_priors_file(path)
    priors, fixed = recovery.truth_priors(settings)
    assert fixed == {"crown_radius_slope": 0.1, "understory_lai": 0.0}
    assert "understory_lai" not in priors and "rho_ratio" in priors
    rng = np.random.default_rng(4)
    for _ in range(20):
        params = recovery.draw_recipe_from_prior(rng, settings).params
        top = params.height_mean + recovery.TOP_SDS * params.height_sd
        assert 12.0 <= top <= 20.0
        assert 0.3 <= params.favd <= 1.2
        assert params.understory_lai == 0.0


def test_truth_priors_accept_a_priors_file_that_sets_the_latent_stem(recovery, tmp_path):
    """A priors file fixing a latent of the tallest stem turns it on; the truth's priors
    are the structure's and ρv/ρg's only."""
    from lidarinv.inference import InversionSettings

    path = tmp_path / "priors.toml"
    path.write_text("[tallest_stem_position]\nfixed = 0.42\n")
    settings = InversionSettings.from_priors_file(path)
    priors, fixed = recovery.truth_priors(settings)
    assert settings.tallest_stem and "tallest_stem_position" not in {**priors, **fixed}


def test_breakdown_finds_off_centring_where_it_is():
    """Intervals centred half a width low on tall stands only: the breakdown by top
    height shows it there and nowhere else, and not by τ."""
    from recovery_breakdown import breakdown

    rng = np.random.default_rng(3)
    probabilities = {"p05": 0.05, "p16": 0.16, "median": 0.5, "p84": 0.84, "p95": 0.95}
    rows = []
    for top in rng.uniform(10.0, 34.0, 3000):
        centre = top + rng.normal() - (0.5 if top >= 22.0 else 0.0)
        posterior = {k: centre + stats.norm.ppf(p) for k, p in probabilities.items()}
        truth = {"top_height": top, "cover": rng.uniform(), "footprint_top_height": top - 0.5}
        rows.append({"truth": truth, "posterior": {"top_height": posterior}, "max_tau": 50.0})
    out = breakdown(rows, "top_height")
    low, middle, high, tallest = out["top_height"]
    assert abs(low["z_median"]) < 0.1 and abs(middle["z_median"]) < 0.1
    assert high["z_median"] == pytest.approx(0.5, abs=0.1)
    assert tallest["z_median"] == pytest.approx(0.5, abs=0.1)
    assert low["coverage_68"] == pytest.approx(0.68, abs=0.05)
    assert [b["n"] for b in out["max_tau"]] == [0, 3000, 0, 0]
    assert out["tallest_stem_below_top_m"] == pytest.approx([0.5, 0.5, 0.5])


def test_breakdown_by_footprint_gap():
    """Intervals centred low by the gap between the stand's top and the footprint's
    tallest stem: the split by that gap finds the shift in the shots with a wide gap;
    runs without explicit stands (NaN tallest stem) fall in no bin."""
    from recovery_breakdown import breakdown

    rng = np.random.default_rng(5)
    probabilities = {"p05": 0.05, "p16": 0.16, "median": 0.5, "p84": 0.84, "p95": 0.95}
    rows = []
    for top, gap in zip(rng.uniform(10.0, 34.0, 3000), rng.exponential(0.8, 3000)):
        centre = top + rng.normal() - (1.0 if gap >= 1.2 else 0.0)
        posterior = {k: centre + stats.norm.ppf(p) for k, p in probabilities.items()}
        truth = {"top_height": top, "cover": 0.5, "footprint_top_height": top - gap}
        rows.append({"truth": truth, "posterior": {"top_height": posterior}, "max_tau": 50.0})
    out = breakdown(rows, "top_height")
    *narrow, wide = out["footprint_gap"]
    assert all(abs(b["z_median"]) < 0.15 for b in narrow)
    assert wide["z_median"] == pytest.approx(1.0, abs=0.15)
    assert sum(b["n"] for b in out["footprint_gap"]) == 3000
    for row in rows:
        row["truth"]["footprint_top_height"] = float("nan")
    assert sum(b["n"] for b in breakdown(rows, "top_height")["footprint_gap"]) == 0


def test_out_of_family_rows_are_summarised_per_stand_kind(recovery):
    """Rows naming a stand kind get a coverage table per kind beside the pooled one; a
    refused shot counts in its kind's shots but not its inverted ones."""
    rng = np.random.default_rng(6)
    rows = []
    for kind, width in (("emergent", 0.1), ("sparse", 1.0)):  # intervals too narrow / right
        for row in gaussian_rows(rng, 400, width):
            row.update(kind=kind, direct={"status": "no ground peak"}, converged=True,
                       start_modes=1, seconds=1.0, log_prob={"truth": np.nan, "best_in_chain": 0})  # fmt: skip
            rows.append(row)
    rows.append({"kind": "sparse", "error": "ground outside window"})
    out = recovery.summarise(rows)
    emergent, sparse = out["by_kind"]["emergent"], out["by_kind"]["sparse"]
    assert (sparse["n_shots"], sparse["n_inverted"], out["n_inverted"]) == (401, 400, 800)
    assert sparse["quantities"]["cover"]["coverage_90"] == pytest.approx(0.9, abs=0.04)
    assert emergent["quantities"]["cover"]["coverage_90"] < 0.3
    pooled = out["quantities"]["cover"]["coverage_90"]
    assert pooled == pytest.approx(np.mean([emergent["quantities"]["cover"]["coverage_90"],
                                            sparse["quantities"]["cover"]["coverage_90"]]))  # fmt: skip
    assert "by_kind" not in sparse


def test_ground_misses_under_a_hidden_ground_flag_are_counted(recovery):
    def row(truth, flags):
        posterior = {"p05": -0.1, "p16": -0.05, "median": 0.0, "p84": 0.05, "p95": 0.1}
        return {
            "truth": {"ground_elevation": truth}, "posterior": {"ground_elevation": posterior},
            "flags": flags, "direct": {"status": "no ground peak"}, "converged": True,
            "start_modes": 1, "seconds": 1.0, "log_prob": {"truth": 0.0, "best_in_chain": 0.0},
        }  # fmt: skip

    hidden = "ground may be hidden: the lowest return …"
    rows = [row(-20.0, [hidden]), row(-20.0, []), row(0.0, [hidden]), row(0.0, [])]
    out = recovery.summarise(rows, by_kind=False)
    assert out["hidden_ground_flagged"] == 2
    ground = out["quantities"]["ground_elevation"]
    assert ground["coverage_90"] == 0.5 and ground["missed_90_hidden_ground_flagged"] == 1


def test_truths_outside_the_prior_support_are_counted_apart(recovery):
    """A closed stand's cover of 1 lies beyond a cover prior ending at 0.99: no interval
    can hold it, and the coverage of the truths inside the support leaves it out."""
    from lidarinv.inference import InversionSettings

    def row(truth, lower, upper):
        posterior = {"p05": lower, "p16": lower, "median": 0.5 * (lower + upper),
                     "p84": upper, "p95": upper}  # fmt: skip
        return {
            "truth": {"cover": truth}, "posterior": {"cover": posterior},
            "direct": {"status": "no ground peak"}, "converged": True, "start_modes": 1,
            "seconds": 1.0, "log_prob": {"truth": 0.0, "best_in_chain": 0.0},
        }  # fmt: skip

    supports = recovery.prior_supports(InversionSettings())
    assert supports["cover"] == (0.001, 0.99)
    rows = [row(1.0, 0.9, 0.99), row(0.5, 0.4, 0.6), row(0.3, 0.4, 0.6), row(0.7, 0.6, 0.8)]
    cover = recovery.summarise(rows, by_kind=False, supports=supports)["quantities"]["cover"]
    assert cover["coverage_90"] == 0.5
    assert cover["outside_prior_support"] == 1
    assert cover["coverage_90_inside_support"] == pytest.approx(2 / 3)
    assert (
        "outside_prior_support"
        not in recovery.summarise(rows, by_kind=False)["quantities"]["cover"]
    )


def test_a_run_is_resummarised_from_its_shots_keeping_its_record(recovery, tmp_path):
    rows = gaussian_rows(np.random.default_rng(3), 50, 1.0)
    for row in rows:
        row.update(direct={"status": "no ground peak"}, converged=True, start_modes=1,
                   seconds=1.0, log_prob={"truth": np.nan, "best_in_chain": 0.0})  # fmt: skip
    (tmp_path / "shots.json").write_text(json.dumps(rows))
    (tmp_path / "summary.json").write_text(json.dumps({"n_shots": 1, "wall_seconds": 12.5}))
    recovery.resummarise(tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["n_shots"] == 50 and summary["wall_seconds"] == 12.5
    assert summary["quantities"]["cover"]["outside_prior_support"] == sum(
        not 0.001 <= r["truth"]["cover"] <= 0.99 for r in rows
    )
