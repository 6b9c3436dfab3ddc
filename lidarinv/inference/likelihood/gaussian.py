"""The observation likelihood: heteroscedastic Gaussian with censored and saturated bins.

Per the physics conventions, y_j = b + a·W_j + ε_j with ε_j ~ N(0, σn² + g·a·W_j). A
model-discrepancy term (:mod:`.discrepancy`) adds to the variance, for the difference
between the one random arrangement of trees in a footprint and the expected stand.
Samples set to the floor are censored, log Φ((floor − μ)/s); samples at the digitiser
maximum are censored from above, log Φ((μ − max)/s). The exactly recorded bins are
summed by a compiled kernel (:func:`gaussian_exact`): the sampler asks for a few rows at
a time, where numpy's per-call cost, not arithmetic, would set the price.
"""

import math

import numpy as np
from scipy.special import log_ndtr

from forward.backends import jit

from ..shot import WindowData
from .covariance import Rotation, covariance_obstacle
from .marginal import _HALF_LOG_2PI, GainMarginal, _unit, gain_marginal_obstacle, linear_fit


class ShotLikelihood:
    """The likelihood of one shot's window, for rows of model waveforms.

    Parameters
    ----------
    data : WindowData
    shot_factor : float (DN)
        g, shot-noise variance per unit signal.
    discrepancy : float
        η, model-discrepancy sd as a fraction of each row's model signal, where no
        discrepancy is fixed for the shot.
    fixed_discrepancy : array (bins,) or (bins, bins) (DN²), optional
        A discrepancy fixed for the shot, used instead of (η·a·W)²: a variance per bin
        (:mod:`.discrepancy`) or a covariance between bins (``lidarinv.inference.
        realisations``), taken in its eigenbasis (:mod:`.covariance`).
    gain_prior : prior, optional
        If given, the gain is integrated out against it (:mod:`.marginal`); that needs a
        variance independent of the gain and no censored or saturated bins, and a
        ValueError says which is missing.
    noise_correlation : AutoregressiveNoise, optional
        Correlated read noise, of covariance σn²·Σ (:mod:`.ar_noise`). The samples, the
        model rows and the baseline's pattern are whitened by L⁻¹ (Σ = LLᵀ) and a fixed
        discrepancy becomes the covariance L⁻¹CL⁻ᵀ; where that is impossible (censored
        or saturated bins, shot noise, a discrepancy proportional to each row's model)
        the noise is taken as white and :attr:`correlation_obstacle` says why.

    Notes
    -----
    log L = Σ_j log N(y_j; b + a·W_j, σn² + g·a·W_j + (η·a·W_j)² + v_j) over exact bins,
    with censored and saturated bins as in :func:`row_log_likelihood`; with a covariance
    C = QΛQᵀ, the supported bins rotated by Qᵀ carry the variances σn² + Λ. With correlated
    noise, log L = log N(L⁻¹y; b·L⁻¹1 + a·L⁻¹W, σn²·I + L⁻¹CL⁻ᵀ) − ½·log det Σ.
    """

    def __init__(self, data, shot_factor=0.0, discrepancy=0.0, fixed_discrepancy=None,
                 gain_prior=None, noise_correlation=None):  # fmt: skip
        self.data = data
        self.shot_factor, self.discrepancy = float(shot_factor), float(discrepancy)
        self.gain_prior = gain_prior
        self.noise_correlation = noise_correlation
        self.rotation = None
        if fixed_discrepancy is not None:
            fixed_discrepancy = np.asarray(fixed_discrepancy, float)
            if fixed_discrepancy.ndim == 2:
                obstacle = covariance_obstacle(data, self.shot_factor)
                if obstacle is not None:
                    raise ValueError(f"a discrepancy covariance cannot be used: {obstacle}")
            else:
                good = np.all(np.isfinite(fixed_discrepancy) & (fixed_discrepancy >= 0))
                if fixed_discrepancy.shape != data.axis.shape or not good:
                    raise ValueError("fixed_discrepancy must be finite, ≥ 0 and one per window bin")
        self.fixed_discrepancy = fixed_discrepancy
        # η of a discrepancy proportional to each row's model: none when the observation
        # fixes the discrepancy
        self.discrepancy_scale = self.discrepancy if fixed_discrepancy is None else 0.0
        self.whitening, self.correlation_obstacle = None, None
        if noise_correlation is not None and noise_correlation.order > 0:
            self.correlation_obstacle = correlation_obstacle(
                data, self.shot_factor, self.discrepancy_scale
            )
            if self.correlation_obstacle is None:
                self.whitening = noise_correlation
        self._basis_data, self._unit, self._log_det_term = data, None, 0.0
        if self.whitening is not None:
            self._whiten_window(fixed_discrepancy)
        elif fixed_discrepancy is not None and fixed_discrepancy.ndim == 2:
            self.rotation = Rotation.of(fixed_discrepancy, data)
            self._basis_data, self._unit = self.rotation.data, self.rotation.unit
        if self.rotation is not None:
            self._fixed_variance = self.rotation.variances
        elif fixed_discrepancy is None or self.whitening is not None:
            self._fixed_variance = np.zeros(data.axis.size)
        else:
            self._fixed_variance = fixed_discrepancy
        self.gain_marginal = None
        if gain_prior is not None:
            obstacle = gain_marginal_obstacle(data, self.shot_factor, self.discrepancy_scale)
            if obstacle is not None:
                raise ValueError(f"the gain cannot be marginalised: {obstacle}")
            self.gain_marginal = GainMarginal(gain_prior)

    def _whiten_window(self, fixed_discrepancy) -> None:
        """The window, the baseline's pattern and the discrepancy in the whitened basis."""
        whiten, data = self.whitening.whiten, self.data
        bins = data.axis.size
        white = WindowData(
            axis=data.axis,
            samples=whiten(data.samples),
            censored=np.zeros(bins, bool),
            saturated=np.zeros(bins, bool),
        )
        unit = whiten(np.ones(bins))
        self._log_det_term = -0.5 * self.whitening.log_det(bins)
        self._basis_data, self._unit = white, unit
        if fixed_discrepancy is None:
            return
        covariance = fixed_discrepancy
        if covariance.ndim == 1:
            covariance = np.diag(covariance)
        whitened = whiten(whiten(covariance).T)  # L⁻¹ C L⁻ᵀ
        self.rotation = Rotation.of(0.5 * (whitened + whitened.T), white, unit)
        self._basis_data, self._unit = self.rotation.data, self.rotation.unit

    def with_fixed_discrepancy(self, fixed_discrepancy) -> "ShotLikelihood":
        """The same likelihood with another fixed discrepancy.

        Parameters
        ----------
        fixed_discrepancy : array (bins,) or (bins, bins) (DN²)
            A variance per bin or a covariance between bins.

        Returns
        -------
        ShotLikelihood
        """
        return ShotLikelihood(
            self.data, self.shot_factor, self.discrepancy, fixed_discrepancy, self.gain_prior,
            self.noise_correlation,
        )  # fmt: skip

    def log_likelihood(self, signal, values):
        """Log-likelihood of rows of model waveforms.

        Parameters
        ----------
        signal : array (n, bins)
            Model waveforms W.
        values : dict
            ``baseline`` and ``noise_sigma`` (DN), and ``gain`` unless it is integrated
            out, (n,) each.

        Returns
        -------
        log_likelihood : array (n,)
        gain_fit : array (n, 4) or None
            Where the gain is integrated out, each row's :func:`.marginal.linear_fit`.
        """
        data, unit = self._basis_data, self._unit
        signal = self.to_basis(signal)
        if self.gain_marginal is None:
            like = row_log_likelihood(
                data, signal, values["gain"], values["baseline"], values["noise_sigma"],
                self.shot_factor, self.discrepancy_scale, self._fixed_variance, unit,
            )  # fmt: skip
            return like + self._log_det_term, None
        fit = linear_fit(
            signal, values["baseline"], values["noise_sigma"], self._fixed_variance, data, unit
        )
        return self.gain_marginal.log_likelihood(fit) + self._log_det_term, fit

    def to_basis(self, rows) -> np.ndarray:
        """Rows of waveforms on the window's bins in the basis where the likelihood is
        evaluated: whitened where the read noise is, then rotated into the discrepancy
        covariance's eigenbasis where there is one.

        Parameters
        ----------
        rows : array (n, bins)

        Returns
        -------
        array (n, bins)
        """
        rows = np.asarray(rows, float)
        if self.whitening is not None:
            rows = self.whitening.whiten(rows)
        if self.rotation is not None:
            rows = self.rotation.rotate(rows)
        return rows

    def in_basis(self) -> tuple:
        """The window in the basis of :meth:`to_basis`.

        Returns
        -------
        samples : array (bins,) (DN)
        unit : array (bins,)
            The baseline's pattern.
        variance : array (bins,) (DN²)
            The fixed discrepancy's variance per component (0 where it has none), to
            which σn² adds: the basis makes the covariance diagonal.
        """
        data = self._basis_data
        unit = np.ones(data.axis.size) if self._unit is None else self._unit
        return data.samples, unit, self._fixed_variance

    def draw_gain(self, fit, rng) -> np.ndarray:
        """Gains drawn from p(a | θ, y), one per row.

        Parameters
        ----------
        fit : array (n, 4)
            :meth:`log_likelihood`'s ``gain_fit``; NaN rows give NaN.
        rng : numpy.random.Generator

        Returns
        -------
        array (n,) (DN per unit reflectance)
        """
        good = np.all(np.isfinite(fit), axis=1)
        gain = np.full(fit.shape[0], np.nan)
        gain[good] = self.gain_marginal.draw(fit[good], rng)
        return gain


def correlation_obstacle(data: WindowData, shot_factor, discrepancy_scale) -> str | None:
    """Why correlated noise cannot be whitened in this likelihood, or None if it can."""
    if discrepancy_scale > 0:
        return "the discrepancy is proportional to each row's model"
    return covariance_obstacle(data, shot_factor)


def row_log_likelihood(
    data: WindowData,
    signal,
    gain,
    baseline,
    noise_sigma,
    shot_factor=0.0,
    discrepancy_scale=0.0,
    fixed_variance=None,
    unit=None,
) -> np.ndarray:
    """Log-likelihood of model waveforms ``signal`` W (n, bins), the fast path.

    Parameters
    ----------
    data : WindowData
        The window's samples (DN) and which are censored or saturated.
    signal : array (n, bins)
        Model waveforms W (apparent reflectance per bin).
    gain, baseline, noise_sigma : array (n,) (DN per unit reflectance, DN, DN)
    shot_factor : float (DN)
        g, shot-noise variance per unit signal.
    discrepancy_scale : float
        η of a discrepancy proportional to each row's model.
    fixed_variance : array (bins,) (DN²), optional
        A variance fixed for the shot (e.g. a discrepancy's, :mod:`.discrepancy`).
    unit : array (bins,), optional
        The baseline's pattern in a rotated basis (:mod:`.covariance`, where every bin
        is exact); ones by default.

    Returns
    -------
    array (n,)

    Notes
    -----
    y_j ~ N(b·1_j + a·W_j, σn² + g·a·W_j + (η·a·W_j)² + v_j) over the exactly recorded
    bins (compiled, :func:`gaussian_exact`), censored bins log Φ((floor − μ)/s) and
    saturated ones log Φ((μ − max)/s) (numpy). ``tests/testing.py`` holds the slow
    reference it is checked against.
    """
    fixed = np.zeros(data.axis.size) if fixed_variance is None else fixed_variance
    total = gaussian_exact(
        signal, gain, baseline, noise_sigma, shot_factor, discrepancy_scale, fixed, data, unit
    )
    limited = data.censored | data.saturated
    if limited.any():
        part = signal[:, limited]
        extra = fixed[limited] + (discrepancy_scale * np.asarray(gain)[:, None] * part) ** 2
        mean, variance = model_moments(part, gain, baseline, noise_sigma, shot_factor, extra)
        sd = np.sqrt(variance)
        c, s = data.censored[limited], data.saturated[limited]
        total += np.sum(log_ndtr((data.floor - mean[:, c]) / sd[:, c]), axis=1)
        total += np.sum(log_ndtr((mean[:, s] - data.saturation) / sd[:, s]), axis=1)
    return total


def model_moments(signal, gain, baseline, noise_sigma, shot_factor=0.0, extra_variance=0.0):
    """Mean and variance of the samples for model waveforms.

    Parameters
    ----------
    signal : array (n, bins)
        The noise-free waveform W (apparent reflectance per bin).
    gain, baseline, noise_sigma : array (n,) (DN per unit reflectance, DN, DN)
    shot_factor : float (DN)
        g.
    extra_variance : float or array (n, bins) (DN²)
        Added, e.g. a model discrepancy (:mod:`.discrepancy`).

    Returns
    -------
    mean, variance : arrays (n, bins) (DN, DN²)
        b + a·W and σn² + g·a·W + extra (physics conventions, "Observation model").
    """
    scaled = np.asarray(gain)[:, None] * signal
    variance = np.asarray(noise_sigma)[:, None] ** 2 + shot_factor * scaled + extra_variance
    return np.asarray(baseline)[:, None] + scaled, variance


@jit
def _gaussian_exact(signal, gain, baseline, noise_sigma, shot_factor, scale, fixed, y, exact, unit):
    n, bins = signal.shape
    out = np.zeros(n)
    for r in range(n):
        a, b, s2 = gain[r], baseline[r], noise_sigma[r] ** 2
        total = 0.0
        for j in range(bins):
            if not exact[j]:
                continue
            w = a * signal[r, j]
            variance = s2 + shot_factor * w + fixed[j] + (scale * w) ** 2
            resid = y[j] - b * unit[j] - w
            total -= 0.5 * (resid * resid / variance + math.log(variance)) + _HALF_LOG_2PI
        out[r] = total
    return out


def gaussian_exact(signal, gain, baseline, noise_sigma, shot_factor, scale, fixed, data, unit=None):
    """Log-likelihood of the exactly recorded bins (compiled).

    Parameters
    ----------
    signal : array (n, bins)
    gain, baseline, noise_sigma : array (n,)
    shot_factor : float (DN)
    scale : float
        η of a discrepancy proportional to the model (0 for none).
    fixed : array (bins,) (DN²)
        A discrepancy variance fixed for the shot (zeros for none).
    data : WindowData
    unit : array (bins,), optional
        The baseline's pattern, ones by default; in a rotated basis (:mod:`.covariance`)
        the rotated ones.

    Returns
    -------
    array (n,)
        Σ_j over exact bins of log N(y_j; b·unit_j + a·W_j, σn² + g·a·W_j + v_j + (η·a·W_j)²).
    """
    return _gaussian_exact(
        np.ascontiguousarray(signal, dtype=np.float64),
        np.ascontiguousarray(gain, dtype=np.float64),
        np.ascontiguousarray(baseline, dtype=np.float64),
        np.ascontiguousarray(noise_sigma, dtype=np.float64),
        float(shot_factor),
        float(scale),
        np.ascontiguousarray(fixed, dtype=np.float64),
        np.ascontiguousarray(data.samples, dtype=np.float64),
        np.ascontiguousarray(data.exact),
        _unit(unit, data),
    )
