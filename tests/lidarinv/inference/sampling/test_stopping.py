"""The stopping rule: ESS and rank-normalised split R̂ of the monitored quantities."""

import numpy as np
import pytest

from lidarinv.inference.model.priors import Uniform
from lidarinv.inference.model.space import Parameter, ParameterSpace
from lidarinv.inference.sampling import SamplerSettings, run_sampler
from lidarinv.inference.sampling.importance import ImportanceSettings
from lidarinv.inference.sampling.stopping import (
    StopRule,
    quantile_mcse,
    quantity_diagnostics,
    sub_ensemble_chains,
)

SPACE = ParameterSpace(Parameter(f"x{i}", "1", Uniform(-30.0, 30.0)) for i in range(2))
#: Half the distance between the bimodal target's modes, in their sd.
SEPARATION = 3.0


def _log_density(log_pdf):
    """A log-posterior of unbounded coordinates with no blobs, as the sampler calls it."""

    def log_posterior(u):
        x, log_jac = SPACE.from_unbounded(u)
        return (log_pdf(x) + SPACE.log_prior(x) + log_jac)[:, None]

    return log_posterior


def gaussian(x):
    return -0.5 * np.sum(x**2, axis=1)


def bimodal(x):
    """Two unit Gaussians of equal weight at x0 = ±SEPARATION."""
    left = -0.5 * ((x[:, 0] + SEPARATION) ** 2 + x[:, 1] ** 2)
    right = -0.5 * ((x[:, 0] - SEPARATION) ** 2 + x[:, 1] ** 2)
    return np.logaddexp(left, right)


#: Moves that cross between the modes seldom: a stretch move from one mode towards a walker
#: in the other lands between them or beyond its own; only the DE moves hop.
SLOW_HOPS = (("stretch", 0.9), ("de", 0.1))


def _run(log_pdf, centres, seed, max_steps=6000):
    settings = SamplerSettings(
        n_walkers=32, max_steps=max_steps, check_every=25, moves=SLOW_HOPS,
        importance=ImportanceSettings(draws=0),  # the chain's rule alone
    )  # fmt: skip
    start = SPACE.to_unbounded(np.atleast_2d(centres))
    rng = np.random.default_rng(seed)
    return run_sampler(_log_density(log_pdf), SPACE, rng, settings, start=start)


def _ar1_walkers(rng, steps, walkers, tau):
    """Stationary AR(1) draws (steps, walkers) of unit variance and integrated τ."""
    a = (tau - 1.0) / (tau + 1.0)
    x = np.empty((steps, walkers))
    x[0] = rng.standard_normal(walkers)
    for t in range(1, steps):
        x[t] = a * x[t - 1] + np.sqrt(1.0 - a * a) * rng.standard_normal(walkers)
    return x


@pytest.mark.parametrize("seed", [1, 2])
def test_the_rule_stops_later_on_a_bimodal_target_than_on_a_gaussian(seed):
    """Walkers start in both modes of the bimodal target (a rule cannot see a mode no walker
    found): R̂ of blocks of walkers, and the long τ of hops between the modes, keep it
    sampling until the modes are mixed; the Gaussian, started at its mode, stops sooner."""
    plain = _run(gaussian, [0.0, 0.0], seed)
    twin = _run(bimodal, [[-SEPARATION, 0.0], [SEPARATION, 0.0]], seed)
    assert plain.converged and twin.converged, (plain.flags, twin.flags)
    assert twin.chain.shape[0] > 1.3 * plain.chain.shape[0]
    assert twin.quantities["x0"]["tau"] > 1.3 * plain.quantities["x0"]["tau"]
    # the result's quantile error is computed once the run has stopped, the rule not asking
    assert 0 < plain.quantities["x0"]["quantile_mcse"] < twin.quantities["x0"]["quantile_mcse"]
    x, _ = SPACE.from_unbounded(twin.chain[twin.burn :].reshape(-1, 2))
    assert 0.35 < np.mean(x[:, 0] > 0) < 0.65  # both modes, near their equal weights


def test_converged_never_where_rhat_exceeds_the_threshold():
    """Over runs stopped by the rule or by short caps, on both targets: a run says converged
    only where every monitored quantity's R̂ (as reported, and recomputed from the kept
    chain) is at most 1.01 and its ESS at least the threshold; otherwise a flag names the
    quantity that failed."""
    rule = StopRule()
    cases = [
        (gaussian, [0.0, 0.0], 6000),
        (bimodal, [[-SEPARATION, 0.0], [SEPARATION, 0.0]], 6000),
        (bimodal, [[-SEPARATION, 0.0], [SEPARATION, 0.0]], 300),
        (bimodal, [-SEPARATION, 0.0], 300),
    ]
    verdicts = []
    for seed, (log_pdf, centres, cap) in enumerate(cases):
        run = _run(log_pdf, centres, seed, max_steps=cap)
        verdicts.append(run.converged)
        recomputed = quantity_diagnostics(
            {name: run.chain[run.burn :, :, i] for i, name in enumerate(SPACE.names)}
        )
        for name, reported in run.quantities.items():
            if run.converged:
                assert reported["rhat"] <= rule.rhat_max
                assert min(reported["ess_bulk"], reported["ess_tail"]) >= rule.ess_min
                assert recomputed[name]["rhat"] <= rule.rhat_max + 0.005  # thinning's noise
        if not run.converged:
            (flag,) = [f for f in run.flags if f.startswith("not converged")]
            assert "x0" in flag or "x1" in flag
    assert verdicts[:2] == [True, True] and verdicts[2:] == [False, False]


def test_rhat_of_blocks_passes_a_mixed_ensemble_that_per_walker_rhat_fails():
    """128 stationary walkers 12 τ long: R̂ taking each walker as a chain is about
    1 + τ/(half a walker's draws) > 1.01, that of four blocks of walkers ≈ 1."""
    import arviz as az

    draws = _ar1_walkers(np.random.default_rng(3), 240, 128, tau=20.0)
    per_walker = float(az.rhat(draws.T, method="rank"))
    assert per_walker > 1.05
    assert quantity_diagnostics({"q": draws})["q"]["rhat"] < 1.01


@pytest.mark.parametrize(
    "change",
    [
        "drift",  # the draws move: early and late halves disagree
        "blocks apart",  # a quarter of the walkers sit elsewhere and never cross
    ],
)
def test_rhat_of_blocks_finds_drift_and_walkers_that_do_not_mix(change):
    rng = np.random.default_rng(4)
    draws = _ar1_walkers(rng, 400, 128, tau=5.0)
    if change == "drift":
        draws += np.linspace(0.0, 1.0, 400)[:, None]
    else:
        draws[:, :32] += 1.0
    assert quantity_diagnostics({"q": draws})["q"]["rhat"] > 1.01


def test_sub_ensemble_chains_put_early_draws_before_late_ones():
    values = np.arange(8 * 6).reshape(8, 6)  # walkers × draws
    chains = sub_ensemble_chains(values, k=4)
    assert chains.shape == (4, 12)
    # block 0 (walkers 0 and 1): their first halves, then their second halves
    np.testing.assert_array_equal(chains[0], [0, 1, 2, 6, 7, 8, 3, 4, 5, 9, 10, 11])


def test_tau_from_the_ess_is_the_ar1_tau_and_not_below_it_on_a_short_chain():
    """τ from ArviZ's bulk ESS matches the AR(1)'s on a long chain, and on a chain five τ
    long is not below what emcee's estimator gives there (emcee's centres each walker on
    its own mean and runs low on short chains)."""
    import emcee

    rng = np.random.default_rng(6)
    long = _ar1_walkers(rng, 4000, 64, tau=20.0)
    assert quantity_diagnostics({"q": long})["q"]["tau"] == pytest.approx(20.0, rel=0.15)
    short = _ar1_walkers(rng, 100, 64, tau=20.0)
    ours = quantity_diagnostics({"q": short})["q"]["tau"]
    theirs = float(emcee.autocorr.integrated_time(short[:, :, None], tol=0, quiet=True)[0])
    assert ours > theirs


@pytest.mark.parametrize(
    "field, value, fails",
    [
        ("rhat", 1.02, "R̂ 1.020 > 1.01"),
        ("ess_bulk", 399.0, "bulk ESS 399 < 400"),
        ("ess_tail", 120.0, "tail ESS 120 < 400"),
        ("tau", 60.0, "chain 8.3 τ < 20 τ"),
        ("rhat", np.nan, "R̂ nan"),
        ("quantile_mcse", 0.14, "quantile MCSE 0.140 sd > 0.1 sd"),
    ],
)
def test_each_threshold_names_the_quantity_and_the_shortfall(field, value, fails):
    passing = {"ess_bulk": 900.0, "ess_tail": 800.0, "rhat": 1.004, "tau": 20.0,
               "quantile_mcse": 0.05}  # fmt: skip
    rule = StopRule(quantile_mcse_max=0.1)
    assert rule.shortfalls({"rh98": passing}, kept_steps=500) == []
    (shortfall,) = rule.shortfalls({"rh98": {**passing, field: value}}, kept_steps=500)
    assert shortfall.startswith("rh98") and fails in shortfall


def test_the_quantile_error_follows_the_draws_and_is_largest_in_a_long_thin_tail():
    """Independent normal draws: the 5 % quantile's standard error is
    √(0.05·0.95)/φ(1.645)/√n ≈ 2.11 sd/√n, its largest. Lognormal draws (σ = 1): the 95 %
    quantile sits where the density is thin and its error, in sd, is about twice that.
    Autocorrelated draws of τ = 10: the error grows, by less than √τ (an indicator of a
    tail decorrelates faster than the draws). ArviZ reads the density at a quantile off
    the sorted draws, which costs its estimate some 20 %."""
    rng = np.random.default_rng(8)
    n = 64 * 1000
    normal = rng.standard_normal((64, 1000))
    assert quantile_mcse(normal) == pytest.approx(2.11 / np.sqrt(n), rel=0.3)
    skewed = quantile_mcse(np.exp(normal))
    assert skewed > 1.5 * quantile_mcse(normal)
    correlated = _ar1_walkers(rng, 1000, 64, tau=10.0).T
    assert (
        1.4 * quantile_mcse(normal) < quantile_mcse(correlated) < np.sqrt(10.0) * 2.11 / np.sqrt(n)
    )


def test_an_unknown_stop_rule_is_refused_by_name():
    with pytest.raises(ValueError, match=r"unknown stop_rule 'never'"):
        run_sampler(
            _log_density(gaussian),
            SPACE,
            np.random.default_rng(0),
            SamplerSettings(stop_rule="never"),
            start=np.zeros(2),
        )


def test_every_result_reports_each_quantitys_ess_and_rhat(tmp_path):
    """The summary text, the batch row and the posterior file carry the monitored
    quantities' bulk and tail ESS and R̂."""
    from tiny_results import tiny_result

    from lidarinv.inference.results.result import InversionResult

    result = tiny_result()
    result.diagnostics["quantities"] = {
        "top_height": {
            "ess_bulk": 812.0,
            "ess_tail": 640.0,
            "rhat": 1.003,
            "tau": 55.0,
            "quantile_mcse": 0.041,
        },
        "rh98": {"ess_bulk": 390.0, "ess_tail": np.nan, "rhat": 1.02, "tau": 80.0},
    }
    line = "ESS bulk/tail, R̂, τ (steps) of the reported quantities: top_height 812/640/1.003/55, rh98 390/nan/1.020/80"
    assert line in result.summary_table().splitlines()
    row = result.summary_row()
    assert (row["min_ess_bulk"], row["min_ess_tail"], row["max_rhat"]) == (390.0, 640.0, 1.02)
    assert row["max_quantile_mcse"] == 0.041
    mcse = "Monte Carlo error of the 5/50/95 % quantiles (posterior sd): top_height 0.041"
    assert mcse in result.summary_table().splitlines()
    result.save(tmp_path / "posterior.h5")
    back = InversionResult.load(tmp_path / "posterior.h5")
    assert back.diagnostics["quantities"]["top_height"]["rhat"] == 1.003
    assert line in back.summary_table().splitlines()


def test_a_quantity_that_does_not_vary_does_not_hold_the_run():
    """A monitored quantity held fixed has no ESS or R̂ and nothing to converge; one with
    non-finite draws fails the rule."""
    constant = quantity_diagnostics({"q": np.full((200, 16), 3.0)})
    assert constant["q"]["tau"] == 0.0 and np.isnan(constant["q"]["rhat"])
    assert StopRule().shortfalls(constant, kept_steps=200) == []
    broken = quantity_diagnostics({"q": np.full((200, 16), np.nan)})
    assert StopRule().shortfalls(broken, kept_steps=200)


def test_a_check_that_stops_on_the_bulk_ess_decides_as_the_whole_rule_does():
    # AR(1) chains 2–60 τ long: the short ones fail on the bulk ESS or the length in τ,
    # which the bulk ESS alone decides; the rule's verdict is the same either way
    rng = np.random.default_rng(5)
    rule = StopRule()
    verdicts = []
    for steps in (40, 200, 600, 1500):
        draws = {"a": _ar1_walkers(rng, steps, 32, 10.0), "b": _ar1_walkers(rng, steps, 32, 25.0)}
        bulk = quantity_diagnostics(draws, bulk_only=True)
        full = quantity_diagnostics(draws)
        for name in draws:
            assert bulk[name]["ess_bulk"] == full[name]["ess_bulk"]
            assert bulk[name]["tau"] == full[name]["tau"]
            assert np.isnan(bulk[name]["rhat"]) and np.isnan(bulk[name]["ess_tail"])
        lazy = rule.bulk_shortfalls(bulk, steps) or rule.shortfalls(full, steps)
        assert bool(lazy) == bool(rule.shortfalls(full, steps))
        assert set(rule.bulk_shortfalls(bulk, steps)) <= set(rule.shortfalls(full, steps))
        verdicts.append(not lazy)
    assert verdicts[0] is False and verdicts[-1] is True  # both outcomes were exercised
