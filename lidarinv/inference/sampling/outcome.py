"""What a sampler run returns: the chain, its diagnostics, and the draws that stand for the
posterior (the chain's after burn-in, or the importance draws that ended the run)."""

from dataclasses import dataclass, field

import numpy as np

from .importance import ImportanceRun


@dataclass
class SamplerRun:
    """Outcome of :func:`run_sampler` (chain arrays exclude nothing: burn-in is ``burn``)."""

    chain: np.ndarray  # (steps, walkers, ndim), unbounded coordinates
    log_prob: np.ndarray  # (steps, walkers)
    blobs: np.ndarray  # (steps, walkers, n_blobs)
    tau: np.ndarray
    tau_history: list
    acceptance: np.ndarray
    converged: bool
    burn: int
    thin: int
    flags: list = field(default_factory=list)
    start_modes: int = 1  # basins the walkers started in (0 for a resumed chain)
    seconds: dict = field(default_factory=dict)  # "start" (MAP search, ball), "sampling"
    # monitored quantity → {"ess_bulk", "ess_tail", "rhat", "tau"} after burn-in
    quantities: dict = field(default_factory=dict)
    # the importance draws that ended the run, if any: the result's draws then
    importance: ImportanceRun | None = None
    importance_tries: list = field(default_factory=list)  # (step, k̂, ESS) of each try

    def draws(self):
        """The posterior's draws: the importance draws where they ended the run, else the
        chain after burn-in, thinned; (u (n, ndim), log-probability (n,), blobs (n, k))."""
        if self.importance is not None:
            return self.importance.u, self.importance.log_prob, self.importance.blobs
        kept = slice(self.burn, None, self.thin)
        return tuple(
            a[kept].reshape(-1, *a.shape[2:]) for a in (self.chain, self.log_prob, self.blobs)
        )

    def coordinate_ess(self) -> np.ndarray:
        """Effective sample size of each sampled coordinate's mean."""
        if self.importance is not None:
            return self.importance.coordinate_ess
        kept = self.chain.shape[0] - self.burn
        return kept * self.chain.shape[1] / np.where(np.isfinite(self.tau), self.tau, np.inf)
