"""The log-posterior of one shot: vectorised over walkers, picklable, never raising.

Invalid parameters (outside the prior support, or describing no stand) get −inf; every
other row a finite value. Rows are evaluated in physical units by :meth:`evaluate`; the
sampler calls the object with unbounded coordinates (see :mod:`.priors`), where the
log-density includes log|dx/du|, and receives the derived quantities as blobs.
"""

from dataclasses import dataclass

import numpy as np

from . import compiled
from .likelihood import WindowData, model_moments, row_log_likelihood
from .parameters import ParameterSpace
from .stand_mapping import DERIVED, StandMapping

#: Blob columns after the log-probability: model-waveform RH metrics, then DERIVED.
BLOB_NAMES = ("rh50", "rh98", *DERIVED)
BLOB_UNITS = {"rh50": "m", "rh98": "m", **DERIVED}


@dataclass
class Evaluation:
    """Terms of the log-posterior for a batch of rows (physical coordinates)."""

    log_prior: np.ndarray
    log_likelihood: np.ndarray
    log_posterior: np.ndarray
    blobs: np.ndarray
    signal: np.ndarray | None = None
    mean: np.ndarray | None = None


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
    fixed_discrepancy : array (bins,) (DN²), optional
        A discrepancy variance fixed by the observation (:mod:`.discrepancy`), used
        instead of (η·a·W)².
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
        if model.heights.shape != data.axis.shape:
            raise ValueError("the expected model's heights do not match the window's axis")
        self.space, self.mapping, self.model, self.data = space, mapping, model, data
        self.shot_factor, self.discrepancy = float(shot_factor), float(discrepancy)
        low, high = (float(b) for b in favd_range)
        if not (0.0 <= low < high):
            raise ValueError(f"favd_range needs 0 <= low < high, got {favd_range}")
        self.favd_range = (low, high)
        if fixed_discrepancy is not None:
            fixed_discrepancy = np.asarray(fixed_discrepancy, float)
            good = np.all(np.isfinite(fixed_discrepancy) & (fixed_discrepancy >= 0))
            if fixed_discrepancy.shape != data.axis.shape or not good:
                raise ValueError("fixed_discrepancy must be finite, ≥ 0 and one per window bin")
        self.fixed_discrepancy = fixed_discrepancy
        self.blob_names = BLOB_NAMES

    @property
    def ndim(self) -> int:
        return self.space.ndim

    def evaluate(self, x, keep_signal=False) -> Evaluation:
        """Log-prior, log-likelihood, log-posterior and blobs of physical rows x (n, ndim)."""
        x = np.atleast_2d(np.asarray(x, float))
        if x.ndim != 2 or x.shape[1] != self.ndim:
            raise ValueError(f"parameters must have shape (n, {self.ndim}), got {x.shape}")
        n = x.shape[0]
        blobs = np.full((n, len(BLOB_NAMES)), np.nan)
        log_like = np.full(n, -np.inf)
        signal = np.zeros((n, self.data.axis.size)) if keep_signal else None
        mean = np.zeros((n, self.data.axis.size)) if keep_signal else None
        with np.errstate(all="ignore"):
            log_prior = self.space.log_prior(np.where(np.isfinite(x), x, np.nan))
            values = self.space.values(x)
            ok = np.isfinite(log_prior) & np.all(np.isfinite(x), axis=1)
            ok[ok] = self.mapping.valid({k: v[ok] for k, v in values.items()})
            if ok.any():
                v = {k: val[ok] for k, val in values.items()}
                vectors, derived = self.mapping.model_vectors(v)
                favd = derived["favd"]
                plausible = (favd >= self.favd_range[0]) & (favd <= self.favd_range[1])
                log_prior[np.flatnonzero(ok)[~plausible]] = -np.inf
                result = self.model.evaluate(vectors)
                like = row_log_likelihood(
                    self.data,
                    result.samples,
                    v["gain"],
                    v["baseline"],
                    v["noise_sigma"],
                    self.shot_factor,
                    self.discrepancy if self.fixed_discrepancy is None else 0.0,
                    self.fixed_discrepancy,
                )
                log_like[ok] = np.where(result.valid, like, -np.inf)
                rh = compiled.relative_heights(
                    result.samples, self.data.axis, v["ground_elevation"]
                )
                blobs[ok] = np.column_stack([rh, *(derived[name] for name in DERIVED)])
                if keep_signal:
                    signal[ok] = result.samples
                    mean[ok] = model_moments(
                        result.samples, v["gain"], v["baseline"], v["noise_sigma"]
                    )[0]
            log_post = log_prior + log_like
        log_post = np.where(np.isfinite(log_post), log_post, -np.inf)
        return Evaluation(log_prior, log_like, log_post, blobs, signal, mean)

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
        log_post = terms.log_posterior + log_jac
        log_post = np.where(np.isfinite(log_post), log_post, -np.inf)
        return np.column_stack([log_post, terms.blobs])
