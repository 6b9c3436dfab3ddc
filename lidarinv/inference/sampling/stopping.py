"""When a run may stop: the effective sample size and R̂ of the quantities it reports.

The rule (:data:`STOP_RULES` ``"ess-rhat"``, the default) asks of every monitored
quantity (the coordinates, or the quantities the result reports: see
:mod:`lidarinv.inference.results.reported`) what Vehtari et al. (2021) ask of a
posterior summary: a rank-normalised split R̂ of at most :attr:`StopRule.rhat_max`, a bulk
and a tail effective sample size of at least :attr:`StopRule.ess_min`, and, on top, a
chain after burn-in at least :attr:`StopRule.min_taus` times the quantity's
autocorrelation time. ArviZ computes them: the ESS with each walker of the ensemble a
chain, R̂ with four blocks of walkers as the chains (:func:`sub_ensemble_chains`). The
rule judges only what the result reports: a coordinate the waveform cannot constrain may
mix slowly without moving the answer. The older rule, ``"tau"`` (``tau_multiple`` times
emcee's τ of every coordinate, stable between checks), is kept for comparison
(``studies/inversion_speed.py --stop-rule``).
"""

from dataclasses import dataclass

import numpy as np

#: Diagnostics of one quantity, in this order (see :func:`quantity_diagnostics`).
DIAGNOSTICS = ("ess_bulk", "ess_tail", "rhat", "tau", "quantile_mcse")
#: Posterior quantiles a result reports (%), whose Monte Carlo error the rule bounds.
REPORTED_QUANTILES = (5.0, 50.0, 95.0)
#: Sub-ensembles whose agreement R̂ judges: the four chains of Vehtari et al. (2021).
SUB_ENSEMBLES = 4


def sub_ensemble_chains(values, k=SUB_ENSEMBLES) -> np.ndarray:
    """The walkers' draws as ``k`` chains, one per block of walkers, for R̂.

    Parameters
    ----------
    values : array (walkers, draws)
    k : int

    Returns
    -------
    array (k, draws // 2 · 2 · walkers // k)
        Chain j holds the first halves of the draws of its block's walkers, then their
        second halves: split R̂ then compares early with late draws and block with
        block. Walkers beyond k equal blocks, and an odd last draw, are left out.

    Notes
    -----
    R̂ of each walker as a chain exceeds 1 by about τ/(draws per half chain) however
    well the ensemble has mixed: 128 walkers 10 τ long give R̂ ≈ 1.1, and R̂ ≤ 1.01 would
    ask for 100 τ. Blocks of walkers are the chains R̂'s thresholds were set for (four
    chains whose pooled ESS is a few hundred), and they disagree where the walkers of
    one block sit in a mode the others do not reach, or the draws drift.
    """
    walkers, draws = values.shape
    k = max(1, min(k, walkers))
    size, half = walkers // k, draws // 2
    blocks = values[: k * size, : 2 * half].reshape(k, size, 2, half)
    return blocks.transpose(0, 2, 1, 3).reshape(k, 2 * size * half)


@dataclass(frozen=True)
class StopRule:
    """Thresholds of the ``"ess-rhat"`` rule.

    Parameters
    ----------
    rhat_max : float
        Largest rank-normalised split R̂ (Vehtari et al. 2021, §4: 1.01, stricter than
        the earlier 1.1, which passes chains that have not mixed), of
        :data:`SUB_ENSEMBLES` blocks of walkers as the chains
        (:func:`sub_ensemble_chains`: per walker, R̂ ≤ 1.01 would ask for 100 τ).
    ess_min : float
        Least bulk and tail ESS (Vehtari et al. 2021 ask for 400, 100 per chain of four:
        R̂ and ESS estimates are then themselves reliable). It also sets the reported
        quantiles' Monte Carlo error: the 5 % quantile of a normal posterior has a
        standard error of √(0.05·0.95)/φ(1.645)/√ESS ≈ 2.1 sd/√ESS, 0.1 sd at ESS 400,
        so two standard errors stay within the 0.2 sd asked of the quantiles.
    min_taus : float
        Least chain length after burn-in, in autocorrelation times τ = walkers·steps/
        bulk ESS of each quantity. An ensemble reaches ESS 400 within a few τ (128
        walkers count as 128 chains), long before the ESS and R̂ estimates can be
        trusted: walkers of one ensemble move together and are not independent chains,
        and an autocorrelation seen over a few τ misses its slow part. Chains cut at
        burn-in plus 5–10 τ of the reported quantities gave their 5/50/95 % quantiles
        within 0.14–0.25 sd of long runs (issue 46), but τ estimated on such a chain
        is itself low (by 1.3–3.6× on an LVIS shot, against a 20 000-step run): 20 τ
        of the estimate is 6–15 τ of the long run's. Measured on two GEDI shots, the
        quantiles at 5, 10 and 20 τ differed from the former 50 τ rule's by up to 0.58,
        0.34 and 0.16 sd, and on a one-storey LVIS shot at 10 and 20 τ by 0.28 and 0.11
        sd (``studies/inversion_speed.py --data``).
    quantile_mcse_max : float or None
        Largest Monte Carlo standard error of each quantity's 5, 50 and 95 % quantiles, in
        posterior sd (:func:`quantile_mcse`); None asks nothing of it. ESS bounds the error
        of a quantile only where the posterior is close to normal: a long, thin tail (top
        height on a sparse stand) puts a 95 % quantile where draws are few, and its error
        at ESS 400 can pass 0.2 sd.
    """

    rhat_max: float = 1.01
    ess_min: float = 400.0
    min_taus: float = 20.0
    quantile_mcse_max: float | None = None

    def shortfalls(self, diagnostics: dict, kept_steps: int) -> list:
        """What keeps the run from stopping, quantity by quantity.

        Parameters
        ----------
        diagnostics : dict of name → dict
            :func:`quantity_diagnostics` of the chain after burn-in.
        kept_steps : int
            Steps after burn-in.

        Returns
        -------
        list of str
            One entry per failed test, naming the quantity and by how much it failed;
            empty where the run may stop.
        """
        out = []
        for name, d in diagnostics.items():
            if d["tau"] == 0:  # a quantity that does not vary has nothing to converge
                continue
            if not np.isfinite(d["rhat"]) or d["rhat"] > self.rhat_max:
                out.append(f"{name} R̂ {d['rhat']:.3f} > {self.rhat_max:g}")
            out.extend(self._bulk_shortfalls(name, d, kept_steps))
            out.extend(_tail_shortfalls(name, d, self.ess_min, self.quantile_mcse_max))
        return out

    def bulk_shortfalls(self, diagnostics: dict, kept_steps: int) -> list:
        """The tests of :meth:`shortfalls` that the bulk ESS alone decides (the chain's
        length in τ and the bulk ESS): where any fails the run cannot stop, whatever the
        tail ESS and R̂, so a check need not compute them.

        Parameters
        ----------
        diagnostics : dict of name → dict
            With ``ess_bulk`` and ``tau`` (:func:`quantity_diagnostics`, ``bulk_only``).
        kept_steps : int

        Returns
        -------
        list of str
        """
        return [
            failed
            for name, d in diagnostics.items()
            if d["tau"] != 0
            for failed in self._bulk_shortfalls(name, d, kept_steps)
        ]

    def importance_shortfalls(
        self, diagnostics: dict, ess_min: float | None = None, mcse_max: float | None = None
    ) -> list:
        """What keeps weighted independent draws (:mod:`.importance`) from standing for
        the posterior, quantity by quantity: the bulk and tail ESS and the quantiles'
        Monte Carlo error, as of a chain (R̂ and τ have no meaning there).

        Parameters
        ----------
        diagnostics : dict of name → dict
            :func:`.importance.importance_sample`'s quantities.
        ess_min : float, optional
            Least bulk and tail ESS; default the rule's.
        mcse_max : float, optional
            Largest quantile MCSE (posterior sd); default the rule's ``quantile_mcse_max``.

        Returns
        -------
        list of str
        """
        out, ess_min = [], self.ess_min if ess_min is None else ess_min
        mcse_max = self.quantile_mcse_max if mcse_max is None else mcse_max
        for name, d in diagnostics.items():
            if d["tau"] == 0:
                continue
            if not d["ess_bulk"] >= ess_min:
                out.append(f"{name} bulk ESS {d['ess_bulk']:.0f} < {ess_min:g}")
            out.extend(_tail_shortfalls(name, d, ess_min, mcse_max))
        return out

    def _bulk_shortfalls(self, name, d, kept_steps) -> list:
        out = []
        if not d["ess_bulk"] >= self.ess_min:
            out.append(f"{name} bulk ESS {d['ess_bulk']:.0f} < {self.ess_min:g}")
        taus = kept_steps / d["tau"] if d["tau"] > 0 else np.nan
        if not taus >= self.min_taus:
            out.append(f"{name} chain {taus:.1f} τ < {self.min_taus:g} τ (τ {d['tau']:.0f})")
        return out


def _tail_shortfalls(name, d, ess_min, mcse_max) -> list:
    """The tail ESS below ``ess_min``, and the quantiles' MCSE above ``mcse_max`` (None or
    infinite: not asked), of one quantity's diagnostics ``d``."""
    out = []
    if not d["ess_tail"] >= ess_min:
        out.append(f"{name} tail ESS {d['ess_tail']:.0f} < {ess_min:g}")
    mcse = d.get("quantile_mcse", np.nan)
    if mcse_max is not None and np.isfinite(mcse_max) and not mcse <= mcse_max:
        out.append(f"{name} quantile MCSE {mcse:.3f} sd > {mcse_max:g} sd")
    return out


def quantity_diagnostics(
    draws: dict, thin: int = 1, quantile_errors: bool = True, bulk_only: bool = False
) -> dict:
    """Bulk and tail ESS, rank-normalised split R̂ and τ of each quantity.

    Parameters
    ----------
    draws : dict of name → array (steps, walkers)
        Each quantity along the chain after burn-in (emcee's layout), thinned by ``thin``.
    thin : int
        The thinning of ``draws``: τ is given in steps of the unthinned chain.
    quantile_errors : bool
        Compute ``quantile_mcse`` (about half again the cost of the rest); NaN if not.
    bulk_only : bool
        Compute only ``ess_bulk`` and ``tau`` (a third of the cost); the rest NaN.

    Returns
    -------
    dict of name → dict
        ``ess_bulk``, ``ess_tail`` (ArviZ ``ess`` methods ``"bulk"`` and ``"tail"``, each
        walker a chain), ``rhat`` (``rhat`` method ``"rank"``, of
        :data:`SUB_ENSEMBLES` blocks of walkers: :func:`sub_ensemble_chains`), ``tau``
        (steps): walkers·steps/bulk ESS, the autocorrelation time the bulk ESS implies,
        and ``quantile_mcse`` (posterior sd, :func:`quantile_mcse`). NaN where a quantity
        is not finite or the chain too short; ``tau`` 0 and the rest NaN where it does not
        vary.

    Notes
    -----
    ArviZ's ESS combines the chains' autocorrelations with their between-chain
    variance (Vehtari et al. 2021, eq. 10), so walkers that have not yet mixed lower it;
    emcee's τ averages each walker's autocorrelation about its own mean and, on a chain
    a few τ long, comes out too low (issue 46: by 1.5–2× at 20 000 steps).

    References
    ----------
    Vehtari, A., Gelman, A., Simpson, D., Carpenter, B. & Bürkner, P.-C. (2021).
    Rank-normalization, folding, and localization: an improved R̂ for assessing
    convergence of MCMC. *Bayesian Analysis* 16, 667–718.
    """
    import arviz as az  # imported on first use: it is slow to import

    out = {}
    for name, values in draws.items():
        values = np.asarray(values, float).T  # (chains, draws)
        if values.shape[1] < 4 or not np.all(np.isfinite(values)):
            out[name] = dict.fromkeys(DIAGNOSTICS, np.nan)
        elif np.ptp(values) == 0:  # held fixed: nothing to wait for
            out[name] = {**dict.fromkeys(DIAGNOSTICS, np.nan), "tau": 0.0}
        else:  # ArviZ's array path: the same functions as for a dataset, without xarray
            ess_bulk = float(az.ess(values, method="bulk"))
            tau = values.size * thin / ess_bulk if ess_bulk > 0 else np.inf
            if bulk_only:
                out[name] = {**dict.fromkeys(DIAGNOSTICS, np.nan), "ess_bulk": ess_bulk, "tau": tau}
                continue
            out[name] = {
                "ess_bulk": ess_bulk,
                "ess_tail": float(az.ess(values, method="tail")),
                "rhat": float(az.rhat(sub_ensemble_chains(values), method="rank")),
                "tau": tau,
                "quantile_mcse": quantile_mcse(values) if quantile_errors else np.nan,
            }
    return {name: out[name] for name in draws}


def quantile_mcse(values) -> float:
    """The largest Monte Carlo standard error of the :data:`REPORTED_QUANTILES`, in
    posterior sd.

    Parameters
    ----------
    values : array (chains, draws)

    Returns
    -------
    float
        max over q of ArviZ's ``mcse(method="quantile", prob=q)`` / sd: the error of a
        quantile from the effective sample size of the indicator x ≤ x_q and the density
        there (Vehtari et al. 2021, §4.3), so that a quantile in a long, thin tail needs
        more draws than the median. NaN where the sd is 0.
    """
    import arviz as az

    sd = float(np.std(values))
    if not sd > 0:
        return np.nan
    errors = [az.mcse(values, method="quantile", prob=q / 100) for q in REPORTED_QUANTILES]
    return float(np.max(errors)) / sd


def coordinates_monitor(names):
    """A monitor of the sampled coordinates themselves, by name.

    Parameters
    ----------
    names : sequence of str

    Returns
    -------
    callable
        (chain (steps, walkers, ndim), blobs) → dict of name → array (steps, walkers).
    """
    names = tuple(names)
    return lambda chain, blobs: {name: chain[..., i] for i, name in enumerate(names)}


#: Stopping rules by name.
STOP_RULES = ("ess-rhat", "tau")
