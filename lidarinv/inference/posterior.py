"""The log-posterior of one shot: vectorised over walkers, picklable, never raising.

Invalid parameters (outside the prior support, or describing no stand) get −inf; every
other row a finite value. Rows are evaluated in physical units by :meth:`evaluate`; the
sampler calls the object with unbounded coordinates (see :mod:`.priors`), where the
log-density includes log|dx/du|, and receives the derived quantities as blobs.
"""

from dataclasses import dataclass

import numpy as np

from . import compiled
from .correlated import Rotation, covariance_obstacle
from .likelihood import WindowData, row_log_likelihood
from .marginal import GainMarginal, gain_marginal_obstacle
from .parameters import ParameterSpace
from .priors import Uniform
from .stand_mapping import DERIVED, TALLEST_STEM, TALLEST_STEM_LATENTS, StandMapping

#: Blob columns after the log-probability: model-waveform RH metrics, then DERIVED.
BLOB_NAMES = ("rh50", "rh98", *DERIVED)
BLOB_UNITS = {"rh50": "m", "rh98": "m", **DERIVED}


@dataclass
class Evaluation:
    """Terms of the log-posterior for a batch of rows (physical coordinates).

    ``signal`` (n, bins) is the model waveform W of each row (with ``keep_signal``);
    ``gain_fit`` (n, 4) the least-squares fit of a marginalised gain
    (:func:`.compiled.linear_fit`), NaN for rows outside the support.
    """

    log_prior: np.ndarray
    log_likelihood: np.ndarray
    log_posterior: np.ndarray
    blobs: np.ndarray
    signal: np.ndarray | None = None
    gain_fit: np.ndarray | None = None


def rh_from_waveform(signal, axis, ground, levels=(0.5, 0.98)) -> np.ndarray:
    """Height above ``ground`` (m) below which each fraction of the energy lies, (n, levels).

    Energy accumulates from the bottom bin edge, linearly within bins.
    """
    dz = axis[1] - axis[0]
    cum = np.cumsum(np.clip(signal, 0.0, None), axis=1)
    total = cum[:, -1:]
    cum = cum / np.where(total > 0, total, 1.0)
    out = np.empty((signal.shape[0], len(levels)))
    rows = np.arange(signal.shape[0])
    for i, level in enumerate(levels):
        k = np.minimum(np.sum(cum < level, axis=1), signal.shape[1] - 1)
        below = np.where(k > 0, cum[rows, np.maximum(k - 1, 0)], 0.0)
        step = cum[rows, k] - below
        frac = np.clip((level - below) / np.where(step > 0, step, 1.0), 0.0, 1.0)
        out[:, i] = axis[0] - dz / 2 + (k + frac) * dz - ground
    out[total[:, 0] <= 0] = np.nan
    return out


class LogPosterior:
    """Log-posterior of one shot.

    Parameters
    ----------
    space : ParameterSpace
    mapping : StandMapping
    model : forward.expected.ExpectedWaveformModel
        Built on the window's axis with ``free=mapping.model_free``.
    data : WindowData
    shot_factor : float
        g, shot-noise variance per unit signal (DN).
    discrepancy : float
        η, model-discrepancy standard deviation as a fraction of the signal.
    fixed_discrepancy : array (bins,) or (bins, bins) (DN²), optional
        A discrepancy fixed for the shot, used instead of (η·a·W)²: a variance per bin
        (:mod:`.discrepancy`) or a covariance between bins (:mod:`.realisations`), which
        the likelihood takes in its eigenbasis (:mod:`.correlated`).

    A gain marked ``marginalised`` in ``space`` is integrated out of the likelihood
    (:mod:`.marginal`); that needs a variance independent of the gain and no censored or
    saturated bins, and a ValueError says which is missing.
    """

    def __init__(
        self,
        space: ParameterSpace,
        mapping: StandMapping,
        model,
        data: WindowData,
        shot_factor=0.0,
        discrepancy=0.0,
        favd_range=(0.0, np.inf),
        fixed_discrepancy=None,
    ):
        if tuple(model.parameter_names) != tuple(mapping.model_free):
            raise ValueError("the expected model must be built with free=mapping.model_free")
        if any(mapping.conditioned != (name in space.by_name) for name in TALLEST_STEM_LATENTS):
            raise ValueError(
                f"a mapping conditioned on the tallest stem needs {TALLEST_STEM_LATENTS} in "
                "the parameter space, and only such a mapping can use them"
            )
        if model.heights.shape != data.axis.shape:
            raise ValueError("the expected model's heights do not match the window's axis")
        self.space, self.mapping, self.model, self.data = space, mapping, model, data
        self.shot_factor, self.discrepancy = float(shot_factor), float(discrepancy)
        low, high = (float(b) for b in favd_range)
        if not (0.0 <= low < high):
            raise ValueError(f"favd_range needs 0 <= low < high, got {favd_range}")
        self.favd_range = (low, high)
        self.rotation = None
        if fixed_discrepancy is not None:
            fixed_discrepancy = np.asarray(fixed_discrepancy, float)
            if fixed_discrepancy.ndim == 2:
                obstacle = covariance_obstacle(data, self.shot_factor)
                if obstacle is not None:
                    raise ValueError(f"a discrepancy covariance cannot be used: {obstacle}")
                self.rotation = Rotation.of(fixed_discrepancy, data)
            else:
                good = np.all(np.isfinite(fixed_discrepancy) & (fixed_discrepancy >= 0))
                if fixed_discrepancy.shape != data.axis.shape or not good:
                    raise ValueError("fixed_discrepancy must be finite, ≥ 0 and one per window bin")
        self.fixed_discrepancy = fixed_discrepancy
        if self.rotation is not None:
            self._fixed_variance = self.rotation.variances
        elif fixed_discrepancy is None:
            self._fixed_variance = np.zeros(data.axis.size)
        else:
            self._fixed_variance = fixed_discrepancy
        # η of a discrepancy proportional to each row's model: none when the observation
        # fixes the discrepancy
        self._discrepancy_scale = self.discrepancy if fixed_discrepancy is None else 0.0
        self.gain_marginal = None
        if "gain" in space.marginalised:
            obstacle = gain_marginal_obstacle(data, self.shot_factor, self._discrepancy_scale)
            if obstacle is not None:
                raise ValueError(f"the gain cannot be marginalised: {obstacle}")
            self.gain_marginal = GainMarginal(space.by_name["gain"].prior)
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

    def with_fixed_discrepancy(self, fixed_discrepancy) -> "LogPosterior":
        """The same posterior with another fixed discrepancy: a variance per bin or a
        covariance between bins (DN²)."""
        return LogPosterior(
            self.space,
            self.mapping,
            self.model,
            self.data,
            self.shot_factor,
            self.discrepancy,
            self.favd_range,
            fixed_discrepancy,
        )

    def evaluate(self, x, keep_signal=False) -> Evaluation:
        """Log-prior, log-likelihood, log-posterior and blobs of physical rows x (n, ndim).

        Rows outside the support are evaluated as a copy of a valid row, so that every
        step works on the whole batch, and masked: −inf log-likelihood, NaN blobs.
        """
        x = np.atleast_2d(np.asarray(x, float))
        if x.ndim != 2 or x.shape[1] != self.ndim:
            raise ValueError(f"parameters must have shape (n, {self.ndim}), got {x.shape}")
        n = x.shape[0]
        with np.errstate(all="ignore"):
            log_prior = self.space.log_prior(x)  # −inf for NaN, ±inf and out-of-bounds values
            values = self.space.values(x)
            ok = np.isfinite(log_prior) & self.mapping.valid(values)
            if not ok.any():
                return self._nothing(log_prior, keep_signal)
            if not ok.all():
                x = np.where(ok[:, None], x, x[np.argmax(ok)])
                values = self.space.values(x)
            vectors, derived = self.mapping.model_vectors(values)
            if self.mapping.conditioned:  # the stem's law replaces its uniform range
                law = derived["tallest_stem_log_density"]
                log_prior = log_prior + law + self._stem_range_log_width
                ok &= np.isfinite(log_prior)
            if self.favd_range != (0.0, np.inf):
                favd = derived["favd"]
                plausible = (favd >= self.favd_range[0]) & (favd <= self.favd_range[1])
                log_prior = np.where(ok & ~plausible, -np.inf, log_prior)
                ok &= plausible
            result = self.model.evaluate(vectors)
            ok &= result.valid
            signal, data, unit = result.samples, self.data, None
            if self.rotation is not None:
                signal = self.rotation.rotate(signal)
                data, unit = self.rotation.data, self.rotation.unit
            gain_fit = None
            if self.gain_marginal is None:
                like = row_log_likelihood(
                    data,
                    signal,
                    values["gain"],
                    values["baseline"],
                    values["noise_sigma"],
                    self.shot_factor,
                    self._discrepancy_scale,
                    self._fixed_variance,
                    unit,
                )
            else:
                gain_fit = compiled.linear_fit(
                    signal,
                    values["baseline"],
                    values["noise_sigma"],
                    self._fixed_variance,
                    data,
                    unit,
                )
                like = self.gain_marginal.log_likelihood(gain_fit)
                gain_fit[~ok] = np.nan
            log_like = np.where(ok, like, -np.inf)
            blobs = np.empty((n, len(BLOB_NAMES)))
            blobs[:, :2] = compiled.relative_heights(
                result.samples, self.data.axis, values["ground_elevation"]
            )
            for column, name in enumerate(DERIVED, start=2):
                blobs[:, column] = derived[name]
            blobs[~ok] = np.nan
            log_post = log_prior + log_like
        log_post = np.where(np.isfinite(log_post), log_post, -np.inf)
        signal = np.where(ok[:, None], result.samples, 0.0) if keep_signal else None
        return Evaluation(log_prior, log_like, log_post, blobs, signal, gain_fit)

    def _nothing(self, log_prior, keep_signal) -> Evaluation:
        """The terms of a batch without a single valid row."""
        n = log_prior.shape[0]
        blobs = np.full((n, len(BLOB_NAMES)), np.nan)
        minus_inf = np.full(n, -np.inf)
        signal = np.zeros((n, self.data.axis.size)) if keep_signal else None
        gain_fit = None if self.gain_marginal is None else np.full((n, 4), np.nan)
        return Evaluation(log_prior, minus_inf, minus_inf.copy(), blobs, signal, gain_fit)

    def draw_marginalised(self, x, rng) -> dict:
        """Posterior draws of the marginalised parameters, one per row of ``x`` (physical
        coordinates of posterior samples): ``{"gain": (n,)}``, or ``{}`` if none; NaN
        for rows outside the support."""
        if self.gain_marginal is None:
            return {}
        fit = self.evaluate(x).gain_fit
        good = np.all(np.isfinite(fit), axis=1)
        gain = np.full(fit.shape[0], np.nan)
        gain[good] = self.gain_marginal.draw(fit[good], rng)
        return {"gain": gain}

    def log_prob(self, x) -> np.ndarray:
        """Log-posterior density of physical rows x (n, ndim): −inf outside the support."""
        return self.evaluate(x).log_posterior

    def log_prob_unbounded(self, u) -> np.ndarray:
        """Log-density in unbounded coordinates u (n, ndim), Jacobian included."""
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
