"""Moves fitted to the chain's own steps (the ``chain-t`` move): when to fit them, and
their last fit kept with an HDF5 chain so that a resumed run makes it again.

A move is adaptive if it has a ``fit(points) -> bool`` method. :func:`.sampling.run_sampler`
fits the adaptive moves at a few early steps and discards the steps before the last fit:
after it every proposal is fixed, and the chain kept is an exact MCMC chain.
"""

import emcee
import numpy as np

#: HDF5 attribute of a chain's group: the step of the adaptive moves' last fit.
LAST_FIT_ATTRIBUTE = "lidarinv_last_fit"


def fit_moves(sampler, adaptive, step=None) -> bool:
    """Fit the adaptive moves to the second half of the chain's first ``step`` steps
    (default: all so far); False where there are none or a fit fails (a move then keeps
    its former fit, or none)."""
    step = sampler.iteration if step is None else step
    chain = sampler.get_chain()
    points = chain[step // 2 : step].reshape(-1, chain.shape[2])
    return bool(adaptive) and all([move.fit(points) for move in adaptive])


def worth_refitting(step, tau, fit_fraction, tau_multiple, max_steps) -> bool:
    """Whether to fit again at ``step``: only while the run, ``tau_multiple`` times the
    latest τ (steps) but at most ``max_steps``, is expected to last at least
    ``step / fit_fraction`` steps, since each fit discards the steps before it. Always
    while τ is unknown, within that cap."""
    expected = tau_multiple * np.max(tau) if np.all(np.isfinite(tau)) else np.inf
    return fit_fraction * min(expected, max_steps) >= step


def record_fit(backend, step):
    """Keep the last fit's step with an HDF5 chain."""
    if isinstance(backend, emcee.backends.HDFBackend):
        with backend.open("a") as handle:
            handle[backend.name].attrs[LAST_FIT_ATTRIBUTE] = step


def refit_on_resume(sampler, adaptive, backend) -> int:
    """On resuming, the adaptive moves' last fit, made again from the stored steps it was
    made from (the same points, the same fit); returns its step (0 if none)."""
    if not adaptive or not isinstance(backend, emcee.backends.HDFBackend):
        return 0
    with backend.open("r") as handle:
        step = int(handle[backend.name].attrs.get(LAST_FIT_ATTRIBUTE, 0))
    return step if step and fit_moves(sampler, adaptive, step) else 0
