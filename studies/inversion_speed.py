"""Wall time per footprint to convergence (issue: Bayesian inversion).

GEDI-like synthetic shots (explicit random stands, see :mod:`lidarinv.examples`)
are inverted on one core, BLAS threads pinned to 1, in two configurations: the default
settings (13 free parameters) and ``10-free`` (baseline and noise σ held at the shot's
estimates, crown-shape mix fixed at half cones). Reported per shot: wall time, steps,
walkers, max τ, converged, the process's CPU time (what one core of its own takes, when
other work shares the machine), the seconds spent simulating a ``realisations`` discrepancy,
and the cost of one log-posterior row (of the pilot posterior, with the per-bin
discrepancy, under ``realisations``). Target: ≤ 10 s per footprint with ~10 free
parameters.

    python studies/inversion_speed.py [--n 3] [--repeats 1] [--max-steps 20000]
                                      [--config default 10-free]
                                      [--sample-gain] [--unbounded logit|probit] [--tag _NAME]
                                      [--discrepancy-model observed|realisations]
                                      [--walkers 128] [--moves de=0.5 ensemble-t=0.5]

Each shot is inverted ``--repeats`` times with other seeds: the time to convergence
follows the largest τ, whose estimate varies from run to run of one posterior.

Real shots, and a time-versus-error curve (issue 46): with ``--data`` (a folder of the
real files, or ``examples`` for those in ``lidarinv/data``) the shots named by
``--gedi-shots`` and ``--lvis-shots`` are inverted, each under every stopping rule asked
for (``--stop-rule ess-rhat tau``; ``--min-taus 5 10`` gives one ``ess-rhat`` variant
each). Where ``--reference-file`` (written by ``studies/reference_posteriors.py``; by
default the test data) holds a shot's long reference run, the shot is inverted with the
reference's seed, so that both sample the same prepared posterior, and each run's
reported quantities' 5/50/95 % quantiles are compared with the reference's, in the
reference's posterior sd; they are also compared with the ``tau`` rule's run of the same
shot and seed where it ran. ``--seed-offset K`` prepares each such shot with the
reference's seed plus K instead: the error then also holds what the preparation's own
randomness (the MAP search, the discrepancy's realisations) moves. ``--combine`` joins
such runs' ``summary.json`` files into one table and curve (where two files hold a shot
under one variant, the later file's run is kept).

    python studies/inversion_speed.py --data ../shared/data/real --gedi-shots ID ...
                                      --lvis-shots ID ... [--stop-rule ess-rhat tau]
                                      [--min-taus 10] [--reference-file PATH]
    python studies/inversion_speed.py --combine SUMMARY.json ... [--tag _NAME]

Writes studies/output/inversion_speed[_TAG]/summary.json and speed.png (synthetic), or
summary.json and time_vs_error.png (``--data``).
"""

import harness

harness.pin_threads()

import json  # noqa: E402
import os  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from reference_posteriors import STORE as REFERENCE_STORE  # noqa: E402
from speed_real_shots import (  # noqa: E402
    compare_with_reference,
    compare_with_tau_rule,
    read_store,
    run_real,
    write_summary,
)

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot  # noqa: E402
from lidarinv.inference import (  # noqa: E402
    InversionSettings,
    SamplerSettings,
    build_problem,
    invert_shot,
)
from lidarinv.inference.likelihood.discrepancy import DISCREPANCY_MODELS  # noqa: E402
from lidarinv.inference.model.prior_table import DEFAULT_UNBOUNDED, UNBOUNDED_MAPS  # noqa: E402
from lidarinv.inference.sampling.stopping import STOP_RULES  # noqa: E402

TARGET_SECONDS = 10.0

#: Configurations by name: changes to the default InversionSettings.
CONFIGURATIONS = {
    "default": {},
    "10-free": {"sample_noise": False, "priors": {"cone_fraction": {"fixed": 0.5}}},
}


def evaluation_cost(problem, rng, batch=32, repeats=20):
    """Seconds per log-posterior row, batched like the sampler (best of repeats)."""
    u = problem.space.to_unbounded(problem.space.sample_prior(rng, batch))
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        problem.log_posterior(u)
        best = min(best, time.perf_counter() - start)
    return best / batch


def _run(settings, n, seed, name, repeats=1):
    """Invert the first ``n`` shots that can be analysed, each ``repeats`` times with
    other seeds (the first as with one); each shot and its inversions draw from their own
    generators, so the shots do not depend on the inversions."""
    rows, i = [], 0
    shots = np.random.SeedSequence(seed)
    while len({row["shot"] for row in rows}) < n:
        shot_seed, run_seed = shots.spawn(2)
        obs = synthetic_shot(
            SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(shot_seed), shot_id=i
        )
        i += 1
        try:
            problem = build_problem(obs, settings)
        except ValueError as error:  # e.g. a return that runs out of the window
            print(name, "skipped:", error, flush=True)
            continue
        for repeat, seeds in enumerate([run_seed, *run_seed.spawn(repeats - 1)]):
            rows.append(_invert_timed(obs, settings, seeds, problem if repeat == 0 else None))
            rows[-1]["repeat"] = repeat
            print(name, rows[-1], flush=True)
    return rows


def _invert_timed(obs, settings, seed, problem=None) -> dict:
    """Wall time and diagnostics of one inversion; the cost of a log-posterior row too
    when ``problem`` is given (measured first, with the inversion's generator)."""
    rng = np.random.default_rng(seed)
    per_row = None if problem is None else evaluation_cost(problem, rng) * 1e6
    start, cpu = time.perf_counter(), time.process_time()
    result = invert_shot(obs, settings, rng=rng)
    seconds = time.perf_counter() - start
    d = result.diagnostics
    return {
        "shot": obs.shot_id,
        "seconds": seconds,
        "cpu_seconds": time.process_time() - cpu,  # one core's own time, whatever the load
        "steps": d["n_steps"],
        "walkers": d["n_walkers"],
        "max_tau": float(np.max(d["tau"])),
        "converged": result.converged,
        "free_parameters": len(result.parameter_names),
        "sampled_parameters": len(d["sampled"]),
        "start_seconds": d["seconds"]["start"],
        "discrepancy_seconds": d["seconds"].get("discrepancy", 0.0),
        "sampling_seconds": d["seconds"]["sampling"],
        "window_bins": int(result.axis.size),
        "microseconds_per_evaluation": per_row,
    }


def _output_folder(tag) -> Path:
    return harness.output_folder("inversion_speed", tag)


def add_sampler_options(parser):
    """--walkers, --moves and --fit-steps, shared with the sampling-coordinates study."""
    parser.add_argument("--walkers", type=int, default=SamplerSettings().n_walkers)
    parser.add_argument(
        "--moves",
        nargs="+",
        metavar="NAME=WEIGHT",
        help="move mixture (names from lidarinv.inference.sampling.moves.MOVES); default the sampler's",
    )
    parser.add_argument(
        "--fit-steps",
        type=int,
        nargs="+",
        help="steps at which the chain-t move is fitted; default the sampler's",
    )


def sampler_changes(args) -> dict:
    """SamplerSettings changes from the options of :func:`add_sampler_options`."""
    changes = {"n_walkers": args.walkers}
    if args.moves:
        pairs = (move.split("=") for move in args.moves)
        changes["moves"] = tuple((name, float(weight)) for name, weight in pairs)
    if args.fit_steps:
        changes["fit_steps"] = tuple(args.fit_steps)
    return changes


def plot_speed(summary, configurations, path):
    """Wall time of each inversion by shot, against the target, and against its largest
    τ (the time to convergence is about 55 τ steps)."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (by_shot, by_tau) = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for k, name in enumerate(configurations):
        rows = summary[name]["shots"]
        colour = f"C{k}"
        for converged, marker in ((True, "o"), (False, "x")):
            picked = [r for r in rows if r["converged"] == converged]
            if not picked:
                continue
            label = name if converged else f"{name}, not converged"
            shots = [r["shot"] + 0.1 * k for r in picked]
            by_shot.scatter(shots, [r["seconds"] for r in picked], c=colour, marker=marker)
            by_tau.scatter(
                [r["max_tau"] for r in picked],
                [r["seconds"] for r in picked],
                c=colour,
                marker=marker,
                label=label,
            )
    for ax in (by_shot, by_tau):
        ax.axhline(TARGET_SECONDS, color="k", lw=0.8, ls="--")
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.yaxis.set_minor_formatter(matplotlib.ticker.ScalarFormatter())
        ax.set_ylabel("wall time to convergence (s, one core)")
    by_shot.set_xlabel("shot")
    by_tau.set_xscale("log")
    by_tau.set_xlabel("largest integrated autocorrelation time τ (steps)")
    by_tau.legend(fontsize=8)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _optional_float(text):
    return None if text.lower() == "none" else float(text)


def main():
    parser = harness.parser(__doc__, seed=5)
    parser.add_argument("--n", type=int, default=3)
    parser.add_argument(
        "--repeats", type=int, default=1, help="inversions of each shot, with other seeds"
    )
    parser.add_argument("--max-steps", type=int, default=SamplerSettings().max_steps)
    parser.add_argument("--config", nargs="+", default=list(CONFIGURATIONS), choices=CONFIGURATIONS)
    parser.add_argument(
        "--sample-gain", action="store_true", help="sample the gain instead of integrating it out"
    )
    parser.add_argument(
        "--unbounded", default=DEFAULT_UNBOUNDED, choices=UNBOUNDED_MAPS, help="sampling map"
    )
    parser.add_argument(
        "--discrepancy-model",
        default=InversionSettings().discrepancy_model,
        choices=sorted(DISCREPANCY_MODELS),
    )
    parser.add_argument(
        "--tallest-stem",
        action="store_const",
        const=True,
        default=InversionSettings().tallest_stem,
        help="condition every footprint on a latent tallest stem (default: the settings', "
        "two-storey stand models only)",
    )
    add_sampler_options(parser)
    parser.add_argument("--data", help="real files: a folder, or 'examples' (lidarinv/data)")
    parser.add_argument(
        "--combine", nargs="+", metavar="SUMMARY",
        help="join the shots of --data runs' summary.json files into one table and curve",
    )  # fmt: skip
    parser.add_argument("--gedi-shots", nargs="+", help="GEDI shot numbers (with --data)")
    parser.add_argument("--lvis-shots", nargs="+", help="LVIS shot numbers (with --data)")
    parser.add_argument("--skip-shots", type=int, default=0,
                        help="leave out the first N shots named (each keeps its seed)")  # fmt: skip
    parser.add_argument("--stop-rule", nargs="+", default=["ess-rhat"], choices=STOP_RULES)
    parser.add_argument(
        "--min-taus", nargs="+", type=float, default=[SamplerSettings().min_taus],
        help="the ess-rhat rule's least chain in τ; one variant each",
    )  # fmt: skip
    parser.add_argument(
        "--quantile-mcse", nargs="+", type=_optional_float, default=[None],
        help="the ess-rhat rule's largest quantile MCSE (sd; 'none': not asked); one variant each",
    )  # fmt: skip
    parser.add_argument(
        "--reference-file", default=str(REFERENCE_STORE),
        help="JSON of the long reference runs (studies/reference_posteriors.py)",
    )  # fmt: skip
    parser.add_argument(
        "--reference-seed", type=int,
        help="seed of shots the reference file does not hold yet (that of their references)",
    )  # fmt: skip
    parser.add_argument(
        "--seed-offset", type=int, default=0,
        help="prepare each referenced shot with its reference's seed plus this: the error "
        "then holds what another MAP search and set of discrepancy realisations change",
    )  # fmt: skip
    args = parser.parse_args()
    if args.combine:
        rows = [row for path in args.combine for row in json.loads(Path(path).read_text())["shots"]]
        # a shot run again under the same variant: the later file's run replaces it
        latest = {(row["instrument"], row["shot"], row["variant"]): row for row in rows}
        rows = list(latest.values())
        references = read_store(args.reference_file)
        for row in rows:  # against the store as it is now
            reference = references.get(f"{row['instrument']}:{row['shot']}")
            if reference is not None:
                compare_with_reference(row, reference)
        for shot in {row["shot"] for row in rows}:
            compare_with_tau_rule(rows, shot)
        variants = list(dict.fromkeys(row["variant"] for row in rows))
        summary = write_summary(rows, variants, references, _output_folder(args.tag))
        print(json.dumps(summary["variants"], indent=1))
        return
    if args.data:
        settings = InversionSettings(
            marginalise_gain=not args.sample_gain,
            unbounded=args.unbounded,
            discrepancy_model=args.discrepancy_model,
            tallest_stem=args.tallest_stem,
        )
        sampler = replace(settings.sampler, max_steps=args.max_steps, **sampler_changes(args))
        summary = run_real(args, replace(settings, sampler=sampler))
        print(json.dumps(summary["variants"], indent=1))
        return
    summary = {"target_seconds": TARGET_SECONDS, "load_average": os.getloadavg()}
    for name in args.config:
        settings = replace(
            InversionSettings(
                marginalise_gain=not args.sample_gain,
                unbounded=args.unbounded,
                discrepancy_model=args.discrepancy_model,
                tallest_stem=args.tallest_stem,
            ),
            **CONFIGURATIONS[name],
        )
        sampler = replace(settings.sampler, max_steps=args.max_steps, **sampler_changes(args))
        settings = replace(settings, sampler=sampler)
        rows = _run(settings, args.n, args.seed, name, args.repeats)
        seconds = np.array([r["seconds"] for r in rows])
        per_shot = {}
        for r in rows:
            per_shot.setdefault(r["shot"], []).append(r["seconds"])
        summary[name] = {
            "median_seconds": float(np.median(seconds)),
            "median_cpu_seconds": float(np.median([r["cpu_seconds"] for r in rows])),
            "within_target_fraction": float(  # converged within the target
                np.mean((seconds <= TARGET_SECONDS) & [r["converged"] for r in rows])
            ),
            "median_seconds_per_shot": {k: float(np.median(v)) for k, v in per_shot.items()},
            "median_ms_per_step": float(
                np.median([r["sampling_seconds"] / r["steps"] * 1e3 for r in rows])
            ),
            "converged_fraction": float(np.mean([r["converged"] for r in rows])),
            "shots": rows,
        }
    summary["gain_marginalised"] = not args.sample_gain
    summary["unbounded"] = args.unbounded
    summary["discrepancy_model"] = args.discrepancy_model
    summary["tallest_stem"] = args.tallest_stem
    summary["walkers"] = args.walkers
    summary["moves"] = [list(m) for m in sampler.moves]
    folder = _output_folder(args.tag)
    harness.write_json(folder / "summary.json", summary)
    plot_speed(summary, args.config, folder / "speed.png")
    brief = {
        k: {kk: vv for kk, vv in v.items() if kk != "shots"}
        for k, v in summary.items()
        if isinstance(v, dict)
    }
    print(json.dumps(brief, indent=1))


if __name__ == "__main__":
    main()
