"""Steps in the log-likelihood of real shots: what a gradient or a sampler trips on.

The expected waveform is computed on grids (bins, fine layers, a coarser depth grid), and
a model that switches grids or paths as a parameter moves can jump where the physics does
not. Each shot named (``INSTRUMENT:SHOT:COHORTS``) is built at default settings with that
stand model (:func:`lidarinv.inference.build_problem`, the per-bin ``observed``
discrepancy), its MAP found (:func:`lidarinv.inference.sampling.start.find_map`), and
``--points`` points drawn from the MAP's Laplace approximation. Through each point, along
each sampled coordinate, the log-likelihood is evaluated on a fine scan of
``--scan-points`` points over ±``--half-width`` (unbounded units, where a prior spans about
±3). A scan's step is the largest |Δₖ − (Δₖ₋₁ + Δₖ₊₁)/2| of its successive differences Δ:
near 0 for a smooth function on so fine a scan (it is a third difference), the jump itself
where the function jumps. Per coordinate the summary gives the largest step and the points
whose step passed ``--threshold``.

    python studies/continuity.py --data DATA --shots lvis:ID:2 gedi:ID:1 ...
        [--points 8] [--scan-points 201] [--half-width 2e-3] [--threshold 0.01]
        [--seed 0] [--tag _NAME] [--before SUMMARY.json]

``--before`` joins an earlier run's summary (e.g. of an older commit, from a worktree):
each coordinate then also holds that run's largest step (``largest_step_before``).

Writes studies/output/continuity[_TAG]/summary.json and steps.png.
"""

import harness

harness.pin_threads()

import json  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from speed_real_shots import real_observations  # noqa: E402

from lidarinv.inference import InversionSettings, build_problem  # noqa: E402
from lidarinv.inference.sampling.start import find_map  # noqa: E402


def scan_steps(log_likelihood, points, coordinate, half_width, scan_points) -> np.ndarray:
    """The largest step of each point's scan along one coordinate.

    Parameters
    ----------
    log_likelihood : callable
        (k, ndim) unbounded rows → (k,).
    points : array (m, ndim)
    coordinate : int
    half_width : float
        Half the scan's length (unbounded units).
    scan_points : int

    Returns
    -------
    array (m,)
        max |Δₖ − (Δₖ₋₁ + Δₖ₊₁)/2| per point; NaN where the scan leaves the support.
    """
    offsets = np.linspace(-half_width, half_width, scan_points)
    rows = np.repeat(points, scan_points, axis=0)
    rows[:, coordinate] += np.tile(offsets, points.shape[0])
    values = log_likelihood(rows).reshape(points.shape[0], scan_points)
    step = np.diff(values, axis=1)
    jump = np.abs(step[:, 1:-1] - 0.5 * (step[:, :-2] + step[:, 2:]))
    out = np.max(jump, axis=1)
    return np.where(np.all(np.isfinite(values), axis=1), out, np.nan)


def shot_steps(observation, cohorts, args, rng) -> dict:
    """One shot's MAP, and per coordinate the largest step and the points past the
    threshold."""
    settings = replace(InversionSettings(), cohorts=cohorts, discrepancy_model="observed")
    problem = build_problem(observation, settings)
    post, space = problem.log_posterior, problem.space
    estimate = find_map(lambda u: post(u)[:, 0], space, rng, settings.sampler)
    points = rng.multivariate_normal(estimate.u, estimate.covariance, size=args.points)
    points = np.vstack([estimate.u, points])

    def log_likelihood(u):
        terms = post.evaluate(space.from_unbounded(u)[0])
        return np.where(np.isfinite(terms.log_prior), terms.log_likelihood, np.nan)

    points = points[np.isfinite(log_likelihood(points))]
    coordinates = []
    for i, name in enumerate(space.names):
        steps = scan_steps(log_likelihood, points, i, args.half_width, args.scan_points)
        finite = steps[np.isfinite(steps)]
        coordinates.append(
            {
                "coordinate": name,
                "largest_step": float(finite.max()) if finite.size else None,
                "points_past_threshold": int(np.sum(finite > args.threshold)),
                "points_scanned": int(finite.size),
            }
        )
    return {
        "instrument": observation.instrument,
        "shot": str(observation.shot_id),
        "cohorts": cohorts,
        "map_log_posterior": float(estimate.log_prob),
        "map_converged": bool(estimate.converged),
        "coordinates": coordinates,
    }


def join_before(shots, before: dict) -> None:
    """Add an earlier run's largest step to each coordinate of the same shot and model."""
    earlier = {
        (s["instrument"], s["shot"], s["cohorts"], c["coordinate"]): c["largest_step"]
        for s in before["shots"]
        for c in s["coordinates"]
    }
    for shot in shots:
        for c in shot["coordinates"]:
            key = (shot["instrument"], shot["shot"], shot["cohorts"], c["coordinate"])
            c["largest_step_before"] = earlier.get(key)


def plot(shots, path, threshold):
    """The largest step per coordinate, one marker per shot."""
    names = list(dict.fromkeys(c["coordinate"] for s in shots for c in s["coordinates"]))
    fig, ax = plt.subplots(figsize=(8, 3.6))
    for k, shot in enumerate(shots):
        steps = {c["coordinate"]: c["largest_step"] for c in shot["coordinates"]}
        x = [i for i, n in enumerate(names) if steps.get(n) is not None]
        y = [max(steps[names[i]], 1e-9) for i in x]
        label = f"{shot['instrument'].upper()} {shot['shot']} ({shot['cohorts']} storey)"
        ax.semilogy(np.array(x) + 0.08 * (k - len(shots) / 2), y, "o", ms=4, label=label)
    ax.axhline(threshold, color="0.5", lw=0.8, ls="--")
    ax.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("largest step of log L")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    parser = harness.parser(__doc__, seed=0)
    parser.add_argument("--data", required=True, help="folder of the real files")
    parser.add_argument("--shots", nargs="+", required=True, help="INSTRUMENT:SHOT:COHORTS")
    parser.add_argument("--points", type=int, default=8)
    parser.add_argument("--scan-points", type=int, default=201)
    parser.add_argument("--half-width", type=float, default=2e-3)
    parser.add_argument("--threshold", type=float, default=0.01)
    parser.add_argument("--before", help="an earlier run's summary.json to set beside")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    shots = []
    for spec in args.shots:
        instrument, shot, cohorts = spec.split(":")
        observation = real_observations(args.data, instrument, [shot])[0]
        shots.append(shot_steps(observation, int(cohorts), args, rng))
        worst = max((c["largest_step"] or 0.0) for c in shots[-1]["coordinates"])
        print(f"{spec}: largest step {worst:.3g}", flush=True)
    if args.before:
        join_before(shots, json.loads(Path(args.before).read_text()))
    folder = harness.output_folder("continuity", args.tag)
    plot(shots, folder / "steps.png", args.threshold)
    summary = {
        "settings": {k: getattr(args, k) for k in ("points", "scan_points", "half_width")},
        "threshold": args.threshold,
        "shots": shots,
        "largest_step": max((c["largest_step"] or 0.0) for s in shots for c in s["coordinates"]),
        "coordinates_past_threshold": sum(
            c["points_past_threshold"] > 0 for s in shots for c in s["coordinates"]
        ),
    }
    harness.write_json(folder / "summary.json", summary)


if __name__ == "__main__":
    main()
