"""Synthetic recovery study of the inversion (issue: Bayesian inversion).

Each footprint is drawn from random stand parameters, realised as an **explicit** random
stand, simulated with the explicit 3-D engine and observed with GEDI-like noise; the
inversion then uses the expected-waveform model, so the random tree arrangement is a
real model error. ``--inverse-crime`` observes the expected waveform instead. For cover,
PAI, top height (the height distribution's upper end), the footprint's tallest stem,
RH98 and gap cover (explicit stands only), mean height and ground elevation the study
reports the coverage of the
68 % and 90 % intervals (with the binomial 95 % range expected at that sample size), the
bias and RMSE of the posterior median, and the same errors of the direct metrics of
``lidarinv.observe.analyse`` on the same waveforms (canopy height above the ground peak,
gap-based cover). It also counts the shots whose chain never came within 5 of the true
parameters' log-posterior: with ``--inverse-crime`` those are search failures (not counted
under the default ``realisations`` discrepancy, whose covariance is drawn in each run;
``--inverse-crime --discrepancy-model observed --discrepancy 0`` tests the sampler alone).
``--truth out-of-family`` draws the stands from outside the model family instead (Weibull
and lognormal heights, two storeys, an emergent tree, clumped stems, sparse and dense
stands: studies/out_of_family_stands.py, whose docstring says which footprint truths
they are compared on) and reports the coverage per kind as well (``by_kind``).

    python studies/recovery.py [--n 200] [--max-steps 4000] [--workers 2]
                               [--inverse-crime] [--discrepancy 0.2]
                               [--discrepancy-model realisations] [--seed 1] [--tag _NAME]
                               [--map-search CANDIDATES STARTS SCREEN POLISH]
                               [--truth study|prior|out-of-family] [--mode-window 5] [--sample-gain]
                               [--ground-prior-sd M]
                               [--realisations COUNT SHRINKAGE BALL]
                               [--priors studies/study_priors.toml]
    python studies/recovery.py --resummarise --tag _NAME

Writes studies/output/recovery[_inverse_crime]/{summary.json,shots.json,*.png}.
"""

import harness

harness.pin_threads()

import json  # noqa: E402
import os  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from dataclasses import asdict, replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

from forward.stand_params import StandParams  # noqa: E402
from lidarinv.examples import ShotRecipe, synthetic_shot  # noqa: E402
from lidarinv.inference import (  # noqa: E402
    InversionSettings,
    RealisationSettings,
    build_problem,
    invert_shot,
)
from lidarinv.inference.likelihood.discrepancy import DISCREPANCY_MODELS, SIMULATED_MODELS  # noqa: E402
from lidarinv.inference.model.parameters import (  # noqa: E402
    DEFAULT_STRUCTURE_PRIORS,
    NUISANCE,
    STRUCTURE,
    default_space,
)
from lidarinv.inference.model.priors import Uniform  # noqa: E402
from lidarinv.inference.model.stand import TOP_SDS, StandMapping, default_template  # noqa: E402
from lidarinv.inference.passes.hidden_ground import HIDDEN_GROUND_FLAG  # noqa: E402
from lidarinv.observe.analyse import analyse  # noqa: E402

#: The truth each posterior quantity is held to, where its name differs: the footprint's
#: RH98 (the expected waveform plus the discrepancy drawn given the data) is an estimate
#: of the noise-free waveform's RH98, as the model's RH98 is; the footprint's crown cover
#: (a realisation of each sample's stand; out-of-family truths only) of the footprint's
#: own, which an out-of-family shot's ``cover`` is.
TRUTH_OF = {"rh98_footprint": "rh98", "footprint_cover": "cover"}
#: Posterior samples given a draw of the footprint's crown cover, for out-of-family truths.
FOOTPRINT_COVER_DRAWS = 256

QUANTITIES = (
    "cover",
    "footprint_cover",
    "gap_cover",
    "pai",
    "top_height",
    "footprint_top_height",
    "rh98",
    "rh98_footprint",
    "mean_height",
    "ground_elevation",
    "gain",
)


def _recipe(rng, cone, **structure) -> ShotRecipe:
    """A truncated-normal stand of the given structure, with random reflectances and
    GEDI-like observation settings."""
    params = StandParams(
        **structure,
        height_family="truncnorm",
        height_truncation=TOP_SDS,
        shape_mix={"cone": cone, "ellipsoid": 1.0 - cone},
        ground_reflectance=0.3,
        canopy_reflectance=0.3 * float(np.clip(rng.normal(1.5, 0.3), 0.8, 2.5)),
    )
    return ShotRecipe(params, gain=rng.uniform(4000.0, 12000.0), baseline=50.0, noise_sigma=2.0)


def draw_recipe(rng, settings=None) -> ShotRecipe:
    """Random stand and GEDI-like observation settings (``settings`` unused: the stands
    come from the study's own ranges)."""
    sd = rng.uniform(1.0, 4.0)
    mean = rng.uniform(8.0, 25.0)
    cone = rng.uniform(0.0, 1.0)
    return _recipe(
        rng,
        cone,
        density=rng.uniform(200.0, 1500.0),
        height_mean=mean,
        height_sd=sd,
        crown_length_ratio=rng.uniform(0.3, 0.7),
        favd=rng.uniform(0.3, 1.2),
        understory_height=rng.uniform(0.5, 2.0),
        understory_lai=rng.uniform(0.0, 0.8),
    )


def truth_priors(settings) -> tuple[dict, dict]:
    """The priors a ``--truth prior`` stand's structure and ρv/ρg are drawn from, and the
    values held fixed: the inversion's own parameter space with the priors file's
    overrides, so that truth and inversion share one prior."""
    placeholder = Uniform(0.0, 1.0)  # the shot-specific nuisance priors are not drawn
    nuisance = {name: placeholder for name in NUISANCE if name != "rho_ratio"}
    latent = settings.latent_stem(settings.cohorts)
    space = default_space(nuisance, settings.priors, tallest_stem=latent)
    drawn = [space.by_name[name] for name in (*STRUCTURE, "rho_ratio")]
    priors = {p.name: p.prior for p in drawn if p.fixed is None}
    return priors, {p.name: p.fixed for p in drawn if p.fixed is not None}


def draw_recipe_from_prior(rng, settings) -> ShotRecipe:
    """A stand whose structure and ρv/ρg are one draw of the inversion's own prior (with
    its FAVD range; ground reflectance, gain and noise as in :func:`draw_recipe`): with
    truths drawn so, intervals that sample the posterior correctly cover at their
    nominal rate."""
    mapping = StandMapping(default_template())
    priors, fixed = truth_priors(settings)
    low, high = (0.0, np.inf) if settings.favd_range is None else settings.favd_range
    while True:
        v = {k: np.array([prior.sample(rng, 1)[0]]) for k, prior in priors.items()}
        v.update({k: np.array([float(x)]) for k, x in fixed.items()})
        v["ground_elevation"] = np.zeros(1)
        if not (mapping.valid(v)[0] and v["top_height"][0] < 50.0):
            continue
        vectors, derived = mapping.model_vectors(v)
        if low <= derived["favd"][0] <= high:
            break
    column = dict(zip(mapping.model_free, vectors[0]))
    recipe = _recipe(
        rng,
        float(v["cone_fraction"][0]),
        **{k: column[k] for k in ("density", "height_mean", "height_sd", "crown_length_ratio")},
        crown_radius_slope=float(v["crown_radius_slope"][0]),
        favd=column["favd"],
        understory_height=float(v["understory_height"][0]),
        understory_lai=float(v["understory_lai"][0]),
    )
    params = replace(recipe.params, canopy_reflectance=0.3 * float(v["rho_ratio"][0]))
    return replace(recipe, params=params)


#: SamplerSettings fields that ``--map-search`` sets, in order.
MAP_SEARCH_FIELDS = ("candidates", "starts", "screen_iterations", "polish")

#: Stand draws by name (``--truth``).
RECIPES = {"study": draw_recipe, "prior": draw_recipe_from_prior}

#: ``--truth`` of stands from outside the model family (studies/out_of_family_stands.py).
OUT_OF_FAMILY = "out-of-family"


def draw_shot(index, rng, explicit, settings, truth, kinds=None):
    """The observation of shot ``index`` for a ``--truth`` choice (out of the family: of
    the stand ``kinds`` in turn, all if None)."""
    if truth == OUT_OF_FAMILY:  # a sibling module: imported here, as the study runs
        from out_of_family_stands import out_of_family_shot

        kind = None if not kinds else kinds[index % len(kinds)]
        return out_of_family_shot(rng, index, kind)
    return synthetic_shot(RECIPES[truth](rng, settings), rng, explicit=explicit, shot_id=index)


def one_shot(task):
    index, seed, explicit, settings, truth, kinds = task
    rng = np.random.default_rng(seed)
    obs = draw_shot(index, rng, explicit, settings, truth, kinds)
    truth = {
        k: float(obs.truth.get(TRUTH_OF.get(k, k), np.nan)) for k in (*QUANTITIES, "rho_ratio")
    }
    row = {"shot": index, "truth": truth}
    if "kind" in obs.truth:
        row["kind"] = obs.truth["kind"]
    direct = analyse(obs)
    row["direct"] = {
        "status": direct.status,
        "canopy_height": float(direct.canopy_height),
        "cover": float(direct.cover),
        "ground": float(direct.ground),
    }
    start = time.perf_counter()
    try:
        result = invert_shot(obs, settings, rng=rng)
    except ValueError as error:
        row["error"] = str(error)
        return row
    row["seconds"] = time.perf_counter() - start
    row["converged"] = result.converged
    row["flags"] = list(result.flags)
    row["max_tau"] = float(np.max(result.diagnostics["tau"]))
    row["cohorts"] = result.settings["cohorts"]
    row["start_modes"] = int(result.diagnostics["start_modes"])
    if "realisations" in result.diagnostics:  # asked, simulated, the first ones' spread
        row["realisations"] = result.diagnostics["realisations"]
    row["sampling"] = result.diagnostics.get("sampling", "chain")  # or importance draws
    row["log_prob"] = {"best_in_chain": result.diagnostics["map_log_prob"]}
    row["log_prob"]["truth"] = truth_log_prob(obs, settings)
    summary = result.summary()
    row["posterior"] = {name: summary[name] for name in QUANTITIES if name in summary}
    return row


def truth_log_prob(obs, settings) -> float:
    """Log-posterior (sampling coordinates) at the true parameters: a chain that never
    comes near it, with the data drawn from the model itself, searched the wrong basin.
    NaN under the ``realisations`` discrepancy, whose covariance is drawn in the run."""
    if settings.discrepancy_model in SIMULATED_MODELS or settings.cohorts != 1:
        return float("nan")
    problem = build_problem(obs, settings)
    space = problem.space
    true_row = np.array([[obs.truth[name] for name in space.names]])
    return float(problem.log_posterior(space.to_unbounded(true_row))[0, 0])


#: Posterior quantiles a shot's row keeps per quantity.
QUANTILE_KEYS = ("p05", "p16", "median", "p84", "p95")


def _inside(row, name, lo, hi) -> bool:
    return row["posterior"][name][lo] <= row["truth"][name] <= row["posterior"][name][hi]


def coverage_of(rows, name, lo, hi):
    return float(np.mean([_inside(r, name, lo, hi) for r in rows]))


def known_rows(rows, name):
    """Rows with a true value of ``name`` (the footprint's tallest stem only exists in an
    explicit stand) and a posterior one (the footprint's cover only where drawn)."""
    return [r for r in rows if np.isfinite(r["truth"].get(name, np.nan)) and name in r["posterior"]]


def standardised_errors(rows, name) -> np.ndarray:
    """z = (truth − median)/(half the 68 % interval) per shot; NaN for a zero width."""
    q = {k: np.array([r["posterior"][name][k] for r in rows]) for k in ("p16", "median", "p84")}
    truth = np.array([r["truth"][name] for r in rows])
    half = 0.5 * (q["p84"] - q["p16"])
    return (truth - q["median"]) / np.where(half > 0, half, np.nan)


def calibration_of(rows, name):
    """How the truths sit in the intervals: the median and robust spread (half the 16–84 %
    range) of z = (truth − median)/(half the 68 % interval), near 0 and 1 for calibrated
    intervals (a spread below 1: too wide; a median off 0: off-centre), and the share of
    truths below the 5 % and above the 95 % quantile (0.05 each when calibrated)."""
    q = {k: np.array([r["posterior"][name][k] for r in rows]) for k in QUANTILE_KEYS}
    truth = np.array([r["truth"][name] for r in rows])
    z16, z50, z84 = np.nanpercentile(standardised_errors(rows, name), [16, 50, 84])
    return {
        "z_median": float(z50),
        "z_spread": float(0.5 * (z84 - z16)),
        "below_p05": float(np.mean(truth < q["p05"])),
        "above_p95": float(np.mean(truth > q["p95"])),
    }


def prior_supports(settings) -> dict:
    """{quantity: (lower, upper)}: the support of the prior of each structural parameter
    the study compares with a truth (the default prior or the settings' override)."""
    out = {}
    for name in QUANTITIES:
        prior = settings.priors.get(name, {}).get("prior") or DEFAULT_STRUCTURE_PRIORS.get(name)
        if prior is not None:
            form = prior.form()
            out[name] = (float(form.lower), float(form.upper))
    return out


def _outside_support(rows, name, support):
    """Truths outside the prior's support, which no posterior interval can hold, and the
    90 % coverage of the others."""
    lower, upper = support
    inside = [r for r in rows if lower <= r["truth"][name] <= upper]
    return {
        "outside_prior_support": len(rows) - len(inside),
        "coverage_90_inside_support": coverage_of(inside, name, "p05", "p95") if inside else None,
    }


def summarise(rows, by_kind=True, supports=None):
    """Coverage, calibration and errors per quantity over the inverted shots; with
    ``by_kind``, the same for each stand kind of rows that name one (``by_kind``); with
    ``supports`` (:func:`prior_supports`), how many truths lie outside their prior's
    support and the coverage of the rest."""
    good = [r for r in rows if "posterior" in r]
    n = len(good)
    out = {"n_shots": len(rows), "n_inverted": n, "quantities": {}}
    if not n:
        return out
    bounds = {
        level: [float(stats.binom.ppf(q, n, level) / n) for q in (0.025, 0.975)]
        for level in (0.68, 0.90)
    }
    out["binomial_95_range"] = {"68": bounds[0.68], "90": bounds[0.90]}
    for name in QUANTITIES:
        known = known_rows(good, name)
        if not known:
            continue
        truth = np.array([r["truth"][name] for r in known])
        median = np.array([r["posterior"][name]["median"] for r in known])
        err = median - truth
        out["quantities"][name] = {
            "n": len(known),
            "coverage_68": coverage_of(known, name, "p16", "p84"),
            "coverage_90": coverage_of(known, name, "p05", "p95"),
            "bias": float(err.mean()),
            "rmse": float(np.sqrt(np.mean(err**2))),
            **calibration_of(known, name),
        }
        if supports and name in supports:
            out["quantities"][name].update(_outside_support(known, name, supports[name]))
    direct_ok = [r for r in good if r["direct"]["status"] == "ok"]
    if direct_ok:
        pairs = {
            "top_height": ("canopy_height", "top_height"),
            "footprint_top_height": ("canopy_height", "footprint_top_height"),
            "cover": ("cover", "cover"),
            "ground_elevation": ("ground", "ground_elevation"),
        }
        for name, (direct_key, truth_key) in pairs.items():
            both = known_rows(direct_ok, truth_key)
            if not both:
                continue
            d = np.array([r["direct"][direct_key] for r in both])
            t = np.array([r["truth"][truth_key] for r in both])
            m = np.array([r["posterior"][name]["median"] for r in both])
            keep = np.isfinite(d)
            out["quantities"][name]["direct_rmse"] = float(np.sqrt(np.mean((d - t)[keep] ** 2)))
            out["quantities"][name]["direct_bias"] = float(np.mean((d - t)[keep]))
            out["quantities"][name]["posterior_rmse_same_shots"] = float(
                np.sqrt(np.mean((m - t)[keep] ** 2))
            )
    hidden = [any(f.startswith(HIDDEN_GROUND_FLAG) for f in r.get("flags", [])) for r in good]
    out["hidden_ground_flagged"] = int(sum(hidden))
    if "ground_elevation" in out["quantities"]:  # the misses the flag explains
        missed = [not _inside(r, "ground_elevation", "p05", "p95") for r in good]
        out["quantities"]["ground_elevation"]["missed_90_hidden_ground_flagged"] = int(
            sum(m and h for m, h in zip(missed, hidden))
        )
    gap = np.array([r["log_prob"]["truth"] - r["log_prob"]["best_in_chain"] for r in good])
    known = np.isfinite(gap)
    out["chain_below_truth_by_5_fraction"] = (
        float(np.mean(gap[known] > 5.0)) if known.any() else None
    )
    out["converged_fraction"] = float(np.mean([r["converged"] for r in good]))
    # the shots whose importance draws ended the run
    out["importance_fraction"] = float(np.mean([r.get("sampling") == "importance" for r in good]))
    out["multi_mode_start_fraction"] = float(np.mean([r["start_modes"] > 1 for r in good]))
    out["median_seconds_per_shot"] = float(np.median([r["seconds"] for r in good]))
    kinds = list(dict.fromkeys(r["kind"] for r in rows if "kind" in r))
    if by_kind and kinds:
        out["by_kind"] = {
            kind: summarise([r for r in rows if r.get("kind") == kind], False, supports)
            for kind in kinds
        }
    return out


def plot(rows, folder):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    good = [r for r in rows if "posterior" in r]
    names = [name for name in QUANTITIES if known_rows(good, name)]
    fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 3.4), squeeze=False)
    for ax, name in zip(axes[0], names):
        known = known_rows(good, name)
        t = np.array([r["truth"][name] for r in known])
        q = {
            k: np.array([r["posterior"][name][k] for r in known]) for k in ("p05", "median", "p95")
        }
        kind = np.array([r.get("kind", "") for r in known])
        for label in dict.fromkeys(kind):  # one colour per stand kind, where rows name one
            i = kind == label
            ax.errorbar(t[i], q["median"][i],
                        yerr=[q["median"][i] - q["p05"][i], q["p95"][i] - q["median"][i]],
                        fmt="o", ms=3, lw=0.7, alpha=0.7, label=label or None)  # fmt: skip
        span = [min(t.min(), q["p05"].min()), max(t.max(), q["p95"].max())]
        ax.plot(span, span, "k--", lw=0.8)
        ax.set_xlabel(f"true {name}")
        ax.set_ylabel("posterior median, 90 %")
    if any("kind" in r for r in good):
        axes[0, 0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(folder / "truth_vs_posterior.png", dpi=100)
    plt.close(fig)


def main():
    parser = harness.parser(__doc__, seed=1, workers=os.cpu_count())
    parser.add_argument("--n", type=int, default=200)
    parser.add_argument("--max-steps", type=int, default=4000)
    parser.add_argument("--inverse-crime", action="store_true")
    parser.add_argument("--discrepancy", type=float, default=InversionSettings().discrepancy)
    parser.add_argument(
        "--discrepancy-model",
        default=InversionSettings().discrepancy_model,
        choices=sorted(DISCREPANCY_MODELS),
    )
    parser.add_argument(
        "--truth",
        default="study",
        choices=sorted([*RECIPES, OUT_OF_FAMILY]),
        help="stands from the study's ranges, from the inversion's structural prior, or "
        "from outside the model family (explicit stands of studies/out_of_family_stands.py)",
    )
    parser.add_argument(
        "--mode-window",
        type=float,
        default=InversionSettings().sampler.mode_window,
        help="start walkers in every basin within this of the best log-posterior (0: one)",
    )
    parser.add_argument(
        "--sample-gain", action="store_true", help="sample the gain instead of integrating it out"
    )
    parser.add_argument(
        "--tallest-stem",
        action="store_const",
        const=True,
        default=InversionSettings().tallest_stem,
        help="condition every footprint on a latent tallest stem (default: the settings', "
        "two-storey stand models only)",
    )
    parser.add_argument(
        "--ground-prior-sd",
        type=float,
        default=None,
        help="sd (m) of the ground prior around the detected peak (default: one bin)",
    )
    parser.add_argument(
        "--realisations",
        nargs=3,
        type=float,
        metavar=("COUNT", "SHRINKAGE", "BALL"),
        help="RealisationSettings of --discrepancy-model realisations (default 64 0.3 1)",
    )
    parser.add_argument(
        "--map-search",
        nargs=4,
        type=int,
        metavar=("CANDIDATES", "STARTS", "SCREEN", "POLISH"),
        help="MAP search settings (SamplerSettings); 512 4 400 4 is the former search",
    )
    parser.add_argument(
        "--priors",
        type=Path,
        help="priors TOML (as `lidarinv invert --priors`); e.g. studies/study_priors.toml, "
        "the ranges the study's stands are drawn from",
    )
    parser.add_argument("--cohorts", choices=("1", "2", "auto"), help="height cohorts")
    parser.add_argument("--kinds", nargs="+", help="out-of-family stand kinds (default: all)")
    parser.add_argument(
        "--resummarise",
        action="store_true",
        help="rewrite the summary of the run of --tag from its shots with this summary code",
    )
    args = parser.parse_args()
    if args.resummarise:
        return resummarise(_output_folder(args.inverse_crime, args.tag))
    if args.truth == OUT_OF_FAMILY and args.inverse_crime:
        parser.error("--inverse-crime has no out-of-family truth")
    choices = dict(
        discrepancy=args.discrepancy,
        discrepancy_model=args.discrepancy_model,
        marginalise_gain=not args.sample_gain,
        ground_prior_sd_m=args.ground_prior_sd,
        tallest_stem=args.tallest_stem,
    )
    if args.ground_prior_sd is None:  # the default, or a priors file's [ground] table
        del choices["ground_prior_sd_m"]
    if args.priors is None:
        settings = InversionSettings(**choices)
    else:
        settings = InversionSettings.from_priors_file(args.priors, **choices)
    if args.realisations:
        count, shrinkage, ball = args.realisations
        simulated = RealisationSettings(count=int(count), shrinkage=shrinkage, ball=ball)
        settings = replace(settings, realisations=simulated)
    sampler = replace(settings.sampler, max_steps=args.max_steps, mode_window=args.mode_window)
    if args.map_search:
        sampler = replace(sampler, **dict(zip(MAP_SEARCH_FIELDS, args.map_search)))
    settings = replace(settings, sampler=sampler)
    seeds = np.random.SeedSequence(args.seed).generate_state(args.n)
    if args.cohorts is not None:
        settings = replace(
            settings, cohorts=args.cohorts if args.cohorts == "auto" else int(args.cohorts)
        )
    if args.truth == OUT_OF_FAMILY:  # their cover is the footprint's own
        settings = replace(settings, footprint_cover_draws=FOOTPRINT_COVER_DRAWS)
    kinds = tuple(args.kinds) if args.kinds else None
    tasks = [
        (i, int(s), not args.inverse_crime, settings, args.truth, kinds)
        for i, s in enumerate(seeds)
    ]
    folder = _output_folder(args.inverse_crime, args.tag)
    folder.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    rows = []
    with ProcessPoolExecutor(args.workers) as pool:
        for row in pool.map(one_shot, tasks):
            rows.append(row)
            print(f"shot {row['shot']}: {row.get('error', 'ok')}", flush=True)
            # kept as they come, so an interrupted run keeps its finished shots
            harness.write_json(folder / "shots.json", rows)
    summary = summarise(rows, supports=prior_supports(settings))
    summary.update(
        {
            "explicit_realisations": not args.inverse_crime,
            "max_steps": args.max_steps,
            "truth": args.truth,
            "kinds": args.kinds,
            "cohorts": settings.cohorts,
            "discrepancy": args.discrepancy,
            "discrepancy_model": args.discrepancy_model,
            "realisations": asdict(settings.realisations),
            "map_search": {k: getattr(settings.sampler, k) for k in MAP_SEARCH_FIELDS},
            "mode_window": args.mode_window,
            "gain_marginalised": not args.sample_gain,
            "tallest_stem": args.tallest_stem,
            "ground_prior_sd_m": args.ground_prior_sd,
            "priors_file": None if args.priors is None else str(args.priors),
            "prior_overrides": settings.describe()["priors"],
            "wall_seconds": time.perf_counter() - start,
            "workers": args.workers,
        }
    )
    harness.write_json(folder / "shots.json", rows)
    harness.write_json(folder / "summary.json", summary)
    if summary["n_inverted"]:
        plot(rows, folder)
    print(json.dumps(summary, indent=1))


def _output_folder(inverse_crime, tag) -> Path:
    name = "recovery_inverse_crime" if inverse_crime else "recovery"
    return harness.OUTPUT / (name + tag)


def resummarise(folder: Path) -> None:
    """Rewrite ``folder``'s summary from its shots with the current :func:`summarise`,
    keeping the run's own record (settings, wall time); its priors file gives the prior
    supports."""
    rows = json.loads((folder / "shots.json").read_text())
    old = json.loads((folder / "summary.json").read_text())
    priors = old.get("priors_file")
    settings = InversionSettings() if priors is None else InversionSettings.from_priors_file(priors)
    summary = summarise(rows, supports=prior_supports(settings))
    record = {k: v for k, v in old.items() if k not in summary}  # the run's settings
    harness.write_json(folder / "summary.json", {**summary, **record})
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
