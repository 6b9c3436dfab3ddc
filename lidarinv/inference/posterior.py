"""The log-posterior of one shot: vectorised over walkers, picklable, never raising.

log p(θ | y) = log π(θ) + log L(y | W(θ)): the prior of the parameter space
(:mod:`.model.space`), the model stage's expected waveform W (:mod:`.model.waveform`) and
the likelihood stage (:mod:`.likelihood.gaussian`). Invalid parameters (outside the prior
support, or describing no stand) get −inf; every other row a finite value. Rows are
evaluated in physical units by :meth:`LogPosterior.evaluate`; the sampler calls the object
with unbounded coordinates (:mod:`.model.priors`), where the log-density includes
log|dx/du|, and receives the derived quantities as blobs.
"""

from dataclasses import dataclass

import numpy as np

from .likelihood.gaussian import ShotLikelihood
from .model.priors import Uniform
from .model.space import ParameterSpace
from .model.stand import DERIVED
from .model.tallest_stem import TALLEST_STEM, TALLEST_STEM_LATENTS
from .model.waveform import WAVEFORM_QUANTITIES, ShotModel

#: Blob columns after the log-probability: model-waveform RH metrics, then DERIVED.
BLOB_NAMES = (*WAVEFORM_QUANTITIES, *DERIVED)
BLOB_UNITS = {**WAVEFORM_QUANTITIES, **DERIVED}


@dataclass
class Evaluation:
    """Terms of the log-posterior for a batch of rows (physical coordinates).

    ``signal`` (n, bins) is the model waveform W of each row (with ``keep_signal``);
    ``gain_fit`` (n, 4) the least-squares fit of a marginalised gain
    (:func:`.likelihood.marginal.linear_fit`), NaN for rows outside the support.
    """

    log_prior: np.ndarray
    log_likelihood: np.ndarray
    log_posterior: np.ndarray
    blobs: np.ndarray
    signal: np.ndarray | None = None
    gain_fit: np.ndarray | None = None


class LogPosterior:
    """Log-posterior of one shot.

    Parameters
    ----------
    space : ParameterSpace
    model : ShotModel
        Parameters → expected waveform on the shot's window.
    likelihood : ShotLikelihood
        Built with ``gain_prior`` where ``space`` marks the gain marginalised.
    favd_range : (float, float) (m²/m³)
        Prior support of the implied FAVD, a joint constraint; (0, inf) for none.
    """

    def __init__(
        self,
        space: ParameterSpace,
        model: ShotModel,
        likelihood: ShotLikelihood,
        favd_range=(0.0, np.inf),
    ):
        mapping = model.mapping
        if any(mapping.conditioned != (name in space.by_name) for name in TALLEST_STEM_LATENTS):
            raise ValueError(
                f"a mapping conditioned on the tallest stem needs {TALLEST_STEM_LATENTS} in "
                "the parameter space, and only such a mapping can use them"
            )
        if model.axis.shape != likelihood.data.axis.shape:
            raise ValueError("the expected model's heights do not match the window's axis")
        if ("gain" in space.marginalised) != likelihood.marginalises_gain:
            raise ValueError("a gain marginalised in the space needs a likelihood given its prior")
        self.space, self.model, self.likelihood = space, model, likelihood
        low, high = (float(b) for b in favd_range)
        if not (0.0 <= low < high):
            raise ValueError(f"favd_range needs 0 <= low < high, got {favd_range}")
        self.favd_range = (low, high)
        self.blob_names = BLOB_NAMES
        stem = space.by_name.get(TALLEST_STEM)
        free_stem = stem is not None and stem.free
        if free_stem and not isinstance(stem.prior, Uniform):
            raise ValueError(
                f"{TALLEST_STEM} takes a uniform range, not a {stem.prior.describe()['kind']} "
                "prior: its law is the stand's, given the other parameters"
            )
        # log of the range's width, the uniform density the law replaces (0: H held)
        self._stem_range_log_width = (
            np.log(stem.prior.upper - stem.prior.lower) if free_stem else 0.0
        )

    @property
    def ndim(self) -> int:
        return self.space.ndim

    @property
    def mapping(self):
        """The model stage's :class:`.model.stand.StandMapping`."""
        return self.model.mapping

    @property
    def data(self):
        """The shot's window (:class:`.shot.WindowData`)."""
        return self.likelihood.data

    def with_likelihood(self, likelihood) -> "LogPosterior":
        """The same prior and model with another likelihood of the same window (e.g. the
        likelihood's ``with_fixed_discrepancy`` under a simulated discrepancy).

        Parameters
        ----------
        likelihood : Likelihood

        Returns
        -------
        LogPosterior
        """
        return LogPosterior(self.space, self.model, likelihood, self.favd_range)

    def evaluate(self, x, keep_signal=False) -> Evaluation:
        """Log-prior, log-likelihood, log-posterior and blobs of physical rows.

        Parameters
        ----------
        x : array (n, ndim)
            The free parameters in physical units.
        keep_signal : bool
            Keep each row's model waveform W.

        Returns
        -------
        Evaluation

        Notes
        -----
        log p = Σ log π_k(x_k) [+ the tallest stem's law given the stand, in place of its
        uniform range] + log L(y | W(x)), −inf where the FAVD leaves ``favd_range``. Rows
        outside the support are evaluated as a copy of a valid row, so that every step works
        on the whole batch, and masked: −inf log-likelihood, NaN blobs.
        """
        x = np.atleast_2d(np.asarray(x, float))
        if x.ndim != 2 or x.shape[1] != self.ndim:
            raise ValueError(f"parameters must have shape (n, {self.ndim}), got {x.shape}")
        with np.errstate(all="ignore"):
            log_prior = self.space.log_prior(x)  # −inf for NaN, ±inf and out-of-bounds values
            values = self.space.values(x)
            ok = np.isfinite(log_prior) & self.model.valid(values)
            if not ok.any():
                return self._nothing(log_prior, keep_signal)
            if not ok.all():
                x = np.where(ok[:, None], x, x[np.argmax(ok)])
                values = self.space.values(x)
            rows = self.model.evaluate(values)
            derived = rows.derived
            if self.mapping.conditioned:  # the stem's law replaces its uniform range
                law = derived["tallest_stem_log_density"]
                log_prior = log_prior + law + self._stem_range_log_width
                ok &= np.isfinite(log_prior)
            if self.favd_range != (0.0, np.inf):
                favd = derived["favd"]
                plausible = (favd >= self.favd_range[0]) & (favd <= self.favd_range[1])
                log_prior = np.where(ok & ~plausible, -np.inf, log_prior)
                ok &= plausible
            ok &= rows.valid
            like, gain_fit = self.likelihood.log_likelihood(rows.signal, values)
            if gain_fit is not None:
                gain_fit[~ok] = np.nan
            log_like = np.where(ok, like, -np.inf)
            blobs = np.empty((x.shape[0], len(BLOB_NAMES)))
            for column, name in enumerate(BLOB_NAMES):
                blobs[:, column] = derived[name]
            blobs[~ok] = np.nan
            log_post = log_prior + log_like
        log_post = np.where(np.isfinite(log_post), log_post, -np.inf)
        signal = np.where(ok[:, None], rows.signal, 0.0) if keep_signal else None
        return Evaluation(log_prior, log_like, log_post, blobs, signal, gain_fit)

    def _nothing(self, log_prior, keep_signal) -> Evaluation:
        """The terms of a batch without a single valid row."""
        n = log_prior.shape[0]
        blobs = np.full((n, len(BLOB_NAMES)), np.nan)
        minus_inf = np.full(n, -np.inf)
        signal = np.zeros((n, self.data.axis.size)) if keep_signal else None
        gain_fit = None if self.likelihood.gain_marginal is None else np.full((n, 4), np.nan)
        return Evaluation(log_prior, minus_inf, minus_inf.copy(), blobs, signal, gain_fit)

    def draw_marginalised(self, x, rng, terms=None) -> dict:
        """Posterior draws of the marginalised parameters, one per posterior sample.

        Parameters
        ----------
        x : array (n, ndim)
            Posterior samples in physical units.
        rng : numpy.random.Generator
        terms : Evaluation, optional
            :meth:`evaluate` of ``x``, where the caller has it already.

        Returns
        -------
        dict
            ``{"gain": (n,)}`` drawn from p(a | θ, y), or ``{}`` if none is marginalised; NaN
            for rows outside the support.
        """
        if self.likelihood.gain_marginal is None:
            return {}
        terms = self.evaluate(x) if terms is None else terms
        return {"gain": self.likelihood.draw_gain(terms.gain_fit, rng)}

    def log_prob(self, x) -> np.ndarray:
        """Log-posterior density of physical rows.

        Parameters
        ----------
        x : array (n, ndim)

        Returns
        -------
        array (n,)
            −inf outside the support.
        """
        return self.evaluate(x).log_posterior

    def log_prob_unbounded(self, u) -> np.ndarray:
        """Log-density in unbounded coordinates, Jacobian included.

        Parameters
        ----------
        u : array (n, ndim)

        Returns
        -------
        array (n,)
        """
        return self(u)[:, 0]

    def __call__(self, u) -> np.ndarray:
        """emcee entry point: (n, 1 + n_blobs) array, log-density in u then the blobs."""
        u = np.atleast_2d(np.asarray(u, float))
        with np.errstate(all="ignore"):
            x, log_jac = self.space.from_unbounded(u)
        terms = self.evaluate(x)
        with np.errstate(invalid="ignore"):  # −inf prior plus an infinite Jacobian
            log_post = terms.log_posterior + log_jac
        log_post = np.where(np.isfinite(log_post), log_post, -np.inf)
        return np.column_stack([log_post, terms.blobs])
