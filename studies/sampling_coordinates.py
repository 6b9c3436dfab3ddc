"""Autocorrelation times of the posterior in each choice of sampling coordinates.

The same GEDI-like synthetic shots (explicit random stands) are sampled for a fixed number
of steps in each set of ridge-straightening coordinates of
:mod:`lidarinv.inference.model.coordinates` (``none``, ``cover-pai``, ``cover-pai+crown-base``,
``cover-pai+ground-centroid``, ``all`` three),
with the bounded priors mapped to the real line by the default logistic map, and in
``cover-pai/probit`` with the normal CDF instead.
The posterior is the same in all of them; what changes is how fast the ensemble crosses
it. τ is estimated per physical parameter and per derived quantity (mean height, crown
volume, LAI) after the chain is mapped back to physical units, so that the numbers
compare across coordinates. Settings as in the speed study's ``10-free`` configuration
(one core, BLAS threads pinned to 1), with the default discrepancy (the simulated
covariance since it was added; ``--discrepancy-model observed`` for the per-bin one). The wall time a run to 50 τ would take is
estimated from the largest τ and the measured cost per step.

    python studies/sampling_coordinates.py [--n 6] [--steps 8000] [--coordinates LABEL ...]
                                           [--discrepancy-model realisations] [--walkers 64]
                                           [--moves de=0.5 ensemble-t=0.5]
                                           [--tag _NAME]

Writes studies/output/sampling_coordinates[_TAG]/summary.json and tau.png.

Real shots (issue 46): with ``--data`` (the folder of the real files) the LVIS shots named
by ``--lvis-shots`` are inverted with the default settings but ``--cohorts`` (2: the
two-storey stand) for ``--steps`` steps in each coordinate set (``default``, the default
ridges; ``default+lower-storey-top``, with the lower storey's top coordinate), the same
seed for each. Reported per run: CPU seconds (the process's own, whatever else shares the
machine) of the whole inversion and of the sampling, acceptance, the τ the sampler
reports (emcee's per sampled coordinate; the monitored quantities' from their bulk ESS),
and τ from the bulk ESS after a fixed burn-in of a quarter of the chain of the reported
quantities in physical units, of the lower storey's parameters, and of its top height
H₂ = ρ·H₁ (the same quantities in every coordinate set, so that they compare).

    python studies/sampling_coordinates.py --data ../shared/data/real --lvis-shots ID ...
                                           [--steps 6000] [--cohorts 2] [--same-start]
                                           [--coordinates default default+lower-storey-top]

Writes studies/output/sampling_coordinates[_TAG]/real.json.

Against the long reference runs (``studies/reference_posteriors.py``): with
``--reference-file`` each shot is prepared once, as ``invert_shot`` prepares it with its
reference's seed, and that posterior is sampled to the default stopping rule in each
coordinate set from the same generator state; the quantiles are compared with the
reference's, in its posterior sd, as ``inversion_speed.py --data`` does.

    python studies/sampling_coordinates.py --data ../shared/data/real --lvis-shots ID ...
        --reference-file tests/data/reference_posteriors.json
        [--coordinates default default+lower-storey-top]

Writes studies/output/sampling_coordinates[_TAG]/references.json; ``--combine TAG ...``
joins such runs into one (with the references they were compared with).
"""

import harness

harness.pin_threads()

import json  # noqa: E402
import time  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from dataclasses import replace  # noqa: E402

import emcee  # noqa: E402
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from inversion_speed import (  # noqa: E402  (studies/ is the script's folder)
    CONFIGURATIONS,
    add_sampler_options,
    sampler_changes,
)

from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot  # noqa: E402
from lidarinv.inference import InversionSettings, build_problem  # noqa: E402
from lidarinv.inference.invert import prepare_problem, sample_prepared  # noqa: E402
from lidarinv.inference.likelihood.discrepancy import DISCREPANCY_MODELS  # noqa: E402
from lidarinv.inference.model import coordinates  # noqa: E402
from lidarinv.inference.model.coordinates import DEFAULT_RIDGES  # noqa: E402
from lidarinv.inference.model.space import ParameterSpace  # noqa: E402
from lidarinv.inference.posterior import BLOB_NAMES, LogPosterior  # noqa: E402
from lidarinv.inference.results.reported import REPORTED, reported_monitor  # noqa: E402
from lidarinv.inference.sampling import run_sampler  # noqa: E402
from lidarinv.inference.sampling.stopping import quantity_diagnostics  # noqa: E402

#: Key of a coordinate set's p of the lower storey's top coordinate (not a setting).
LOWER_POWER = "lower_top_power"

#: Coordinate sets compared, by label: changes to InversionSettings (ridge coordinates and
#: the map of bounded priors to the real line).
COORDINATES = {
    "none": {"ridges": ()},
    "cover-pai": {"ridges": ("cover-pai",)},
    "cover-pai+crown-base": {"ridges": ("cover-pai", "crown-base")},
    "cover-pai+ground-centroid": {"ridges": ("cover-pai", "ground-centroid")},
    "all": {"ridges": ("cover-pai", "crown-base", "ground-centroid")},
    "cover-pai/probit": {"ridges": ("cover-pai",), "unbounded": "probit"},
    "default": {"ridges": DEFAULT_RIDGES},
    "default+lower-storey-top": {"ridges": (*DEFAULT_RIDGES, "lower-storey-top")},
    "default+mean-height": {"ridges": (*DEFAULT_RIDGES, "mean-height")},
    "default+mean-height+lower-storey-top": {
        "ridges": (*DEFAULT_RIDGES, "mean-height", "lower-storey-top")
    },
    # p = 1: the crown base's logistic form (LOWER_POWER is not a setting: the study's own)
    "default+lower-storey-top/p=1": {
        "ridges": (*DEFAULT_RIDGES, "lower-storey-top"),
        LOWER_POWER: 1.0,
    },
}

#: The coordinate sets compared on real shots by default.
REAL_COORDINATES = ("default", "default+lower-storey-top")

#: The lower storey's parameters and derived top height, whose τ is reported on real shots.
LOWER_STOREY = ("cohort2_fraction", "cohort2_top_ratio", "cohort2_sd_ratio", "cohort2_top")

#: Derived quantities whose τ is reported besides the parameters.
DERIVED = ("mean_height", "crown_volume", "lai")

#: The speed study's 10-free configuration.
TEN_FREE = CONFIGURATIONS["10-free"]


def physical_tau(problem, run, burn):
    """τ (steps) of each free parameter and DERIVED quantity, in physical units."""
    chain = run.chain[burn:]
    steps, walkers, ndim = chain.shape
    x, _ = problem.space.from_unbounded(chain.reshape(-1, ndim))
    blobs = run.blobs[burn:]
    columns = [BLOB_NAMES.index(name) for name in DERIVED]
    series = np.concatenate([x.reshape(steps, walkers, ndim), blobs[..., columns]], axis=2)
    tau = emcee.autocorr.integrated_time(series, tol=0, quiet=True)
    return dict(zip((*problem.space.names, *DERIVED), (float(t) for t in tau)))


def run_shot(obs, settings, seed):
    rng = np.random.default_rng(seed)
    prepared = prepare_problem(obs, settings, rng)
    problem, centre = prepared.problem, prepared.start
    start = time.perf_counter()
    run = run_sampler(problem.log_posterior, problem.space, rng, settings.sampler, start=centre)
    seconds = time.perf_counter() - start
    steps = run.chain.shape[0]
    tau = physical_tau(problem, run, steps // 4)
    max_tau = max(tau.values())
    return {
        "seconds": seconds,
        "seconds_per_step": seconds / steps,
        "tau": tau,
        "max_tau": max_tau,
        "seconds_to_50_tau": 50.0 * max_tau * seconds / steps,
        "acceptance": float(np.mean(run.acceptance)),
    }


@contextmanager
def lower_top_power(power):
    """Spaces built inside take p = ``power`` for the lower storey's top (None: the
    default, :data:`coordinates.LOWER_TOP_WALL_POWER`)."""
    default = coordinates.LOWER_TOP_WALL_POWER
    coordinates.LOWER_TOP_WALL_POWER = default if power is None else power
    try:
        yield
    finally:
        coordinates.LOWER_TOP_WALL_POWER = default


def in_coordinates(prepared, changes):
    """The prepared posterior, start included, in other sampling coordinates: the same
    parameters, likelihood and physical start."""
    space = prepared.problem.space
    with lower_top_power(changes.get(LOWER_POWER)):
        other = ParameterSpace(space.parameters, changes["ridges"],
                               changes.get("unbounded", space.unbounded),
                               space.interception_slope, space.backend)  # fmt: skip
    posterior = prepared.problem.log_posterior
    posterior = LogPosterior(other, posterior.model, posterior.likelihood, posterior.favd_range)
    start = other.to_unbounded(space.from_unbounded(prepared.start)[0])
    return posterior, start


def physical_draws(space, blob_names, run, burn) -> dict:
    """{name: (steps, walkers)} after ``burn`` of the reported quantities in physical
    units (sampled ones mapped back from the coordinates) and of :data:`LOWER_STOREY`."""
    chain, blobs = run.chain[burn:], run.blobs[burn:]
    steps, walkers, ndim = chain.shape
    with np.errstate(all="ignore"):
        x, _ = space.from_unbounded(chain.reshape(-1, ndim))
    values = space.values(x)
    out = {}
    for name in REPORTED:
        if name in space.names:
            out[name] = values[name].reshape(steps, walkers)
        elif name in blob_names:
            out[name] = blobs[..., blob_names.index(name)]
    if "cohort2_top_ratio" in values:
        values["cohort2_top"] = values["cohort2_top_ratio"] * values["top_height"]
    for name in LOWER_STOREY:
        if name in values:
            out[name] = values[name].reshape(steps, walkers)
    return out


def run_real_shot(obs, settings, changes, seed, prepared=None) -> dict:
    """One fixed-length inversion of a real shot in the coordinates ``changes``: CPU
    seconds, acceptance, the τ the sampler reports and the τ of :func:`physical_draws`
    after a quarter of the chain. From ``prepared`` (its posterior and start, mapped to
    these coordinates) if given, else prepared in them."""
    rng = np.random.default_rng(seed)
    cpu = time.process_time()
    if prepared is None:
        settings = replace(settings, **{k: v for k, v in changes.items() if k != LOWER_POWER})
        with lower_top_power(changes.get(LOWER_POWER)):
            prepared = prepare_problem(obs, settings, rng)
        posterior, start = prepared.problem.log_posterior, prepared.start
    else:
        posterior, start = in_coordinates(prepared, changes)
    space = posterior.space
    sampling_cpu = time.process_time()
    run = run_sampler(
        posterior, space, rng, settings.sampler, start=start,
        monitor=reported_monitor(space, posterior.blob_names),
    )  # fmt: skip
    now = time.process_time()
    steps = run.chain.shape[0]
    draws = physical_draws(space, posterior.blob_names, run, steps // 4)
    physical = quantity_diagnostics(draws)
    return {
        "signature": space.signature().split(";")[0],
        "cpu_seconds": now - cpu,
        "sampling_cpu_seconds": now - sampling_cpu,
        "steps": steps,
        "acceptance": float(np.mean(run.acceptance)),
        "coordinate_tau": dict(zip(space.names, (float(t) for t in run.tau))),
        "monitored_tau": {name: d["tau"] for name, d in run.quantities.items()},
        "physical": physical,
        "max_reported_tau": float(max(physical[n]["tau"] for n in REPORTED if n in physical)),
        "posterior": storey_shape(draws),
    }


def storey_shape(draws) -> dict:
    """5/50/95 % quantiles of the top heights and the lower storey's ratio, and the
    correlations along the ridge: corr(H₁, ρ) and corr(H₁, H₂)."""
    if "cohort2_top" not in draws:
        return {}
    names = ("top_height", "cohort2_top_ratio", "cohort2_top", "cohort2_fraction")
    out = {n: [float(q) for q in np.percentile(draws[n], (5, 50, 95))] for n in names}
    top, ratio, lower = (draws[n].ravel() for n in names[:3])
    out["corr_top_ratio"] = float(np.corrcoef(top, ratio)[0, 1])
    out["corr_top_lower_top"] = float(np.corrcoef(top, lower)[0, 1])
    return out


def against_references(shots, labels, store, folder) -> list:
    """Each shot prepared once, as ``invert_shot`` prepares it with its reference's seed,
    then sampled to the default stopping rule in each coordinate set from the same
    generator state, its quantiles compared with the reference's
    (:func:`speed_real_shots.compare_with_reference`). The ``default`` set's run is the
    one ``invert_shot`` gives."""
    from speed_real_shots import _run_record, compare_with_reference

    rows = []
    for obs in shots:
        reference = store[f"{obs.instrument}:{obs.shot_id}"]
        rng = np.random.default_rng(reference["seed"])
        cpu = time.process_time()
        prepared = prepare_problem(obs, InversionSettings(), rng)
        prepare_cpu, state = time.process_time() - cpu, rng.bit_generator.state
        for label in labels:
            posterior, start = in_coordinates(prepared, COORDINATES[label])
            problem = replace(prepared.problem, log_posterior=posterior)
            rng.bit_generator.state = state
            cpu, wall = time.process_time(), time.perf_counter()
            result = sample_prepared(replace(prepared, problem=problem, start=start), rng)
            cpu, wall = time.process_time() - cpu + prepare_cpu, time.perf_counter() - wall
            row = {"shot": str(obs.shot_id), "instrument": obs.instrument, "coordinates": label,
                   "acceptance": float(np.mean(result.diagnostics["acceptance"]))}  # fmt: skip
            row.update(_run_record(result, wall, cpu))
            compare_with_reference(row, reference)
            rows.append(row)
            brief = {k: row[k] for k in ("shot", "coordinates", "cpu_seconds", "steps",
                                         "converged", "max_error_sd", "acceptance")}  # fmt: skip
            print(json.dumps(brief), flush=True)
            harness.write_json(folder / "references.json", {"runs": rows})
    return rows


def combine_reference_runs(tags, folder) -> dict:
    """Join the ``references.json`` of runs tagged ``tags`` (a shot and coordinate set
    once, the last tag's run kept), with the reference runs they were compared with."""
    from reference_posteriors import STORE
    from speed_real_shots import held_references, read_store

    runs = {}
    for tag in tags:
        path = harness.output_folder("sampling_coordinates", tag) / "references.json"
        for row in json.loads(path.read_text())["runs"]:
            runs[(row["shot"], row["coordinates"])] = row
    rows = sorted(runs.values(), key=lambda r: (r["shot"], r["coordinates"]))
    summary = {"runs": rows, "references": held_references(read_store(STORE), rows)}
    harness.write_json(folder / "references.json", summary)
    return summary


def main_real(args):
    """:func:`run_real_shot` of each real LVIS shot in each coordinate set."""
    from speed_real_shots import read_store, real_observations

    shots = real_observations(args.data, "lvis", args.lvis_shots)
    labels = [label for label in args.coordinates if label in COORDINATES]
    if args.reference_file:
        folder = harness.output_folder("sampling_coordinates", args.tag)
        return against_references(shots, labels, read_store(args.reference_file), folder)
    base = InversionSettings(cohorts=args.cohorts)
    sampler = replace(base.sampler, max_steps=args.steps, stop_rule="tau", tau_multiple=1e9,
                      **sampler_changes(args))  # fmt: skip
    base = replace(base, sampler=sampler)
    folder = harness.output_folder("sampling_coordinates", args.tag)
    rows = []
    for obs, seed in zip(shots, np.random.SeedSequence(args.seed).generate_state(len(shots))):
        shared, prepare_cpu = None, 0.0
        if args.same_start:  # one posterior and start, prepared in the first coordinates
            cpu = time.process_time()
            first = COORDINATES[labels[0]]
            settings = replace(base, **{k: v for k, v in first.items() if k != LOWER_POWER})
            shared = prepare_problem(obs, settings, np.random.default_rng(int(seed)))
            prepare_cpu = time.process_time() - cpu
        for label in labels:
            row = {"shot": str(obs.shot_id), "coordinates": label, "same_start": args.same_start}
            row.update(run_real_shot(obs, base, COORDINATES[label], int(seed), shared))
            row["cpu_seconds"] += prepare_cpu
            rows.append(row)
            brief = {k: row[k] for k in ("shot", "coordinates", "cpu_seconds", "acceptance",
                                         "max_reported_tau")}  # fmt: skip
            brief["posterior"] = row["posterior"]
            brief["tau"] = {k: round(v["tau"]) for k, v in row["physical"].items()
                            if np.isfinite(v["tau"])}  # fmt: skip
            print(json.dumps(brief), flush=True)
            harness.write_json(folder / "real.json", {"steps": args.steps, "runs": rows})
    return rows


def plot(summary, path):
    labels = [label for label in COORDINATES if label in summary["shots"][0]]
    width = 0.8 / len(labels)
    names = list(summary["shots"][0][labels[0]]["tau"])
    fig, ax = plt.subplots(figsize=(9, 4))
    for k, label in enumerate(labels):
        tau = np.array([[shot[label]["tau"][n] for n in names] for shot in summary["shots"]])
        x = np.arange(len(names)) + (k - (len(labels) - 1) / 2) * width
        ax.bar(x, np.median(tau, axis=0), width=width, label=label)
        ax.plot(np.repeat(x[None], tau.shape[0], 0), tau, "k.", ms=3)
    ax.set_xticks(np.arange(len(names)), names, rotation=45, ha="right")
    ax.set_ylabel("integrated autocorrelation time τ (steps)")
    ax.set_title("τ per quantity, median over shots (dots: shots)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    parser = harness.parser(__doc__, seed=11)
    parser.add_argument("--n", type=int, default=6)
    parser.add_argument("--steps", type=int, default=8000)
    parser.add_argument("--coordinates", nargs="+", choices=COORDINATES)
    parser.add_argument(
        "--discrepancy-model",
        default=InversionSettings().discrepancy_model,
        choices=sorted(DISCREPANCY_MODELS),
    )
    parser.add_argument("--data", help="the folder of the real files (real LVIS shots)")
    parser.add_argument("--lvis-shots", nargs="+", help="LVIS shot numbers (with --data)")
    parser.add_argument("--cohorts", type=int, default=2, help="height cohorts (with --data)")
    parser.add_argument(
        "--same-start",
        action="store_true",
        help="real shots: prepare each shot once (in the first coordinates) and sample that "
        "posterior from the same physical start in each",
    )
    parser.add_argument(
        "--reference-file",
        help="real shots: sample each to the default stopping rule from its reference's "
        "prepared posterior (a reference_posteriors.py store) and compare the quantiles",
    )
    parser.add_argument(
        "--combine",
        nargs="+",
        metavar="TAG",
        help="join the references.json of --reference-file runs with these tags (into --tag)",
    )
    add_sampler_options(parser)
    args = parser.parse_args()
    if args.combine:
        combine_reference_runs(
            args.combine, harness.output_folder("sampling_coordinates", args.tag)
        )
        return
    if args.data:
        args.coordinates = args.coordinates or list(REAL_COORDINATES)
        main_real(args)
        return
    args.coordinates = args.coordinates or [c for c in COORDINATES if c not in REAL_COORDINATES]
    rng = np.random.default_rng(args.seed)
    base = replace(InversionSettings(discrepancy_model=args.discrepancy_model), **TEN_FREE)
    # a fixed length: τ is compared at equal cost, not at convergence
    sampler = replace(base.sampler, max_steps=args.steps, stop_rule="tau", tau_multiple=1e9,
                      **sampler_changes(args))  # fmt: skip
    base = replace(base, sampler=sampler)
    shots, skipped, i = [], [], 0
    while len(shots) < args.n:
        obs = synthetic_shot(SYNTHETIC_SHOTS["gedi-mixed"], rng, shot_id=i)
        seed, i = int(rng.integers(2**32)), i + 1
        row = {"shot": obs.shot_id}
        try:
            build_problem(obs, base)
        except ValueError as error:  # e.g. a return running out of the window
            skipped.append(str(error))
            continue
        for label in args.coordinates:
            row[label] = run_shot(obs, replace(base, **COORDINATES[label]), seed)
            worst = max(row[label]["tau"], key=row[label]["tau"].get)
            print(obs.shot_id, label, f"max τ {row[label]['max_tau']:.0f} ({worst})", flush=True)
        shots.append(row)
    medians = {
        label: {
            key: float(np.median([shot[label][key] for shot in shots]))
            for key in ("max_tau", "seconds_per_step", "seconds_to_50_tau", "acceptance")
        }
        for label in args.coordinates
    }
    summary = {
        "steps": args.steps,
        "walkers": args.walkers,
        "moves": [list(m) for m in base.sampler.moves],
        "n": args.n,
        "discrepancy_model": args.discrepancy_model,
        "median": medians,
        "shots": shots,
        "skipped": skipped,
    }
    folder = harness.output_folder("sampling_coordinates", args.tag)
    harness.write_json(folder / "summary.json", summary)
    plot(summary, folder / "tau.png")
    print(json.dumps(medians, indent=1))


if __name__ == "__main__":
    main()
