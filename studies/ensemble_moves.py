"""Autocorrelation time of emcee move mixtures on a correlated Gaussian, by walker count.

The sampler's coordinates straighten the GEDI posterior until it is close to a Gaussian on
most shots; this measures what each move mixture of :data:`lidarinv.inference.sampling.moves.MOVES`
does on an exact one (9 dimensions, like the 10-free configuration with the gain
integrated out; a random covariance with condition number in the thousands). Reported per
mixture and walker count: the largest τ (steps), the acceptance fraction, and the largest
relative error of the sampled variances (a check that every mixture samples the target).

    python studies/ensemble_moves.py [--ndim 9] [--steps 6000] [--walkers 32 64 96]
                                     [--tag _NAME]

Writes studies/output/ensemble_moves[_TAG]/summary.json and tau.png.
"""

import emcee
import matplotlib

matplotlib.use("Agg")
import harness
import matplotlib.pyplot as plt
import numpy as np

from lidarinv.inference.sampling.moves import MOVES

#: Mixtures compared, by label.
MIXTURES = {
    "de/snooker/stretch 0.7/0.1/0.2": (("de", 0.7), ("de-snooker", 0.1), ("stretch", 0.2)),
    "de/ensemble-t 0.5/0.5": (("de", 0.5), ("ensemble-t", 0.5)),
    "ensemble-t": (("ensemble-t", 1.0),),
    "de/kde 0.5/0.5": (("de", 0.5), ("kde", 0.5)),
}


def gaussian_target(ndim, rng):
    """A log-density of N(0, Σ) for a random Σ, and Σ."""
    a = rng.normal(size=(ndim, ndim))
    covariance = a @ a.T + 0.1 * np.eye(ndim)
    precision = np.linalg.inv(covariance)

    def log_prob(x):
        return -0.5 * np.einsum("ij,jk,ik->i", x, precision, x)

    return log_prob, covariance


def run(mixture, walkers, steps, log_prob, covariance, seed):
    rng = np.random.default_rng(seed)
    ndim = covariance.shape[0]
    start = rng.multivariate_normal(np.zeros(ndim), covariance, size=walkers)
    moves = [(MOVES[name](), weight) for name, weight in mixture]
    sampler = emcee.EnsembleSampler(walkers, ndim, log_prob, vectorize=True, moves=moves)
    sampler.random_state = np.random.RandomState(seed).get_state()
    sampler.run_mcmc(start, steps, progress=False)
    burn = steps // 6
    tau = emcee.autocorr.integrated_time(sampler.get_chain(discard=burn), tol=0, quiet=True)
    variance = sampler.get_chain(discard=burn, flat=True).var(axis=0)
    return {
        "max_tau": float(np.max(tau)),
        "acceptance": float(np.mean(sampler.acceptance_fraction)),
        "variance_error": float(np.max(np.abs(variance / np.diag(covariance) - 1.0))),
    }


def main():
    parser = harness.parser(__doc__, seed=0)
    parser.add_argument("--ndim", type=int, default=9)
    parser.add_argument("--steps", type=int, default=6000)
    parser.add_argument("--walkers", type=int, nargs="+", default=[32, 64, 96])
    args = parser.parse_args()
    log_prob, covariance = gaussian_target(args.ndim, np.random.default_rng(args.seed))
    rows = []
    for label, mixture in MIXTURES.items():
        for walkers in args.walkers:
            row = {"mixture": label, "walkers": walkers}
            row.update(run(mixture, walkers, args.steps, log_prob, covariance, args.seed + 1))
            rows.append(row)
            print(row, flush=True)
    folder = harness.output_folder("ensemble_moves", args.tag)
    summary = {
        "ndim": args.ndim,
        "steps": args.steps,
        "condition_number": float(np.linalg.cond(covariance)),
        "runs": rows,
    }
    harness.write_json(folder / "summary.json", summary)
    fig, ax = plt.subplots(figsize=(6, 4))
    for label in MIXTURES:
        mine = [r for r in rows if r["mixture"] == label]
        ax.plot([r["walkers"] for r in mine], [r["max_tau"] for r in mine], "o-", label=label)
    ax.set_xlabel("walkers")
    ax.set_ylabel("largest τ (steps)")
    ax.set_yscale("log")
    ax.set_title(f"{args.ndim}-dimensional Gaussian")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(folder / "tau.png", dpi=120)


if __name__ == "__main__":
    main()
