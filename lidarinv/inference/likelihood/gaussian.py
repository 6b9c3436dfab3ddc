"""The observation likelihood: heteroscedastic Gaussian with censored and saturated bins.

Per the physics conventions, y_j = b + a·W_j + ε_j with ε_j ~ N(0, σn² + g·a·W_j). A
model-discrepancy term (:mod:`.discrepancy`) adds to the variance, for the difference
between the one random arrangement of trees in a footprint and the expected stand.
Samples set to the floor are censored, log Φ((floor − μ)/s); samples at the digitiser
maximum are censored from above, log Φ((μ − max)/s); the row terms are in
:mod:`.gaussian_rows`. The likelihood owns its noise model (:meth:`ShotLikelihood.for_shot`)
and answers the questions of :class:`.protocol.Likelihood`.
"""

from functools import cached_property

import numpy as np

from ..shot import WindowData
from . import conditional
from .ar_noise import AutoregressiveNoise
from .covariance import Rotation, covariance_obstacle
from .gaussian_rows import model_moments, row_log_likelihood
from .marginal import (
    GainMarginal,
    gain_marginal_obstacle,
    linear_fit,
)
from .predictive import gaussian_replicates, recorded

#: How the note of a likelihood that took the read noise as white begins.
WHITE_NOISE_NOTE = "read noise taken as white"


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
    following : FollowingCovariance, optional
        A discrepancy covariance scaled by each row's own stand (:mod:`.following`): the
        log-likelihood is then taken under it, while the predictive draws, the
        discrepancy given the data and the gain's draws keep ``fixed_discrepancy``, the
        pilot's. Needs a fixed covariance and every bin exactly recorded.

    Notes
    -----
    log L = Σ_j log N(y_j; b + a·W_j, σn² + g·a·W_j + (η·a·W_j)² + v_j) over exact bins,
    with censored and saturated bins as in :func:`row_log_likelihood`; with a covariance
    C = QΛQᵀ, the supported bins rotated by Qᵀ carry the variances σn² + Λ. With correlated
    noise, log L = log N(L⁻¹y; b·L⁻¹1 + a·L⁻¹W, σn²·I + L⁻¹CL⁻ᵀ) − ½·log det Σ.
    """

    def __init__(self, data, shot_factor=0.0, discrepancy=0.0, fixed_discrepancy=None,
                 gain_prior=None, noise_correlation=None, following=None):  # fmt: skip
        self.data = data
        self.following = following
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
        if following is not None and (fixed_discrepancy is None or fixed_discrepancy.ndim != 2):
            raise ValueError("a following covariance needs the pilot's fixed covariance too")
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
        return type(self)(
            self.data, self.shot_factor, self.discrepancy, fixed_discrepancy, self.gain_prior,
            self.noise_correlation,
        )  # fmt: skip

    def with_following(self, following) -> "ShotLikelihood":
        """The same likelihood, its log-likelihood under a covariance that follows each
        row's stand (:mod:`.following`).

        Parameters
        ----------
        following : FollowingCovariance

        Returns
        -------
        ShotLikelihood
        """
        return type(self)(
            self.data, self.shot_factor, self.discrepancy, self.fixed_discrepancy,
            self.gain_prior, self.noise_correlation, following,
        )  # fmt: skip

    @classmethod
    def for_shot(cls, window, noise, settings, fixed_discrepancy=None) -> "ShotLikelihood":
        """The likelihood of a shot's window, with the noise model fitted to its measured
        noise (the registry's constructor, :data:`lidarinv.inference.likelihood.LIKELIHOODS`).

        Parameters
        ----------
        window : WindowData
        noise : lidarinv.observe.NoiseModel or None
            The shot's measured noise (σ, autocorrelation and where they came from).
        settings : InversionSettings
            ``shot_factor``, ``discrepancy`` (η) and ``correlated_noise``.
        fixed_discrepancy : array (bins,) or (bins, bins) (DN²), optional

        Returns
        -------
        ShotLikelihood
            Without a gain prior (:meth:`with_gain_prior` adds one).
        """
        correlation = AutoregressiveNoise.of_measured(noise) if settings.correlated_noise else None
        return cls(
            window, settings.shot_factor, settings.discrepancy, fixed_discrepancy, None, correlation
        )

    def with_gain_prior(self, gain_prior) -> "ShotLikelihood":
        """The same likelihood with the gain integrated out against ``gain_prior``."""
        return type(self)(
            self.data, self.shot_factor, self.discrepancy, self.fixed_discrepancy, gain_prior,
            self.noise_correlation, self.following,
        )  # fmt: skip

    @property
    def holds_noise(self) -> bool:
        """The read noise is whitened, so its mean and σ are held at the shot's estimates
        (a sampled σn would fit the whitened residuals, not the noise's marginal σ)."""
        return self.whitening is not None

    @property
    def marginalises_gain(self) -> bool:
        """The gain is integrated out (a gain prior was given)."""
        return self.gain_marginal is not None

    @property
    def gain_obstacle(self) -> str | None:
        """Why the gain cannot be integrated out exactly here, or None if it can."""
        return gain_marginal_obstacle(self.data, self.shot_factor, self.discrepancy_scale)

    @property
    def conditioning_obstacle(self) -> str | None:
        """Why the discrepancy cannot be drawn given the data, or None if it can
        (:func:`.conditional.conditioning_obstacle`)."""
        return conditional.conditioning_obstacle(self)

    @property
    def notes(self) -> list:
        """Where the likelihood had to simplify the shot's noise, what it did."""
        if self.correlation_obstacle is None:
            return []
        return [f"{WHITE_NOISE_NOTE}: {self.correlation_obstacle}"]

    def predictive_moments(self, signal, values) -> tuple:
        """Mean and per-bin variance of the samples given rows of model waveforms.

        Parameters
        ----------
        signal : array (n, bins)
            Model waveforms W.
        values : dict of arrays (n,)
            ``gain``, ``baseline`` and ``noise_sigma`` (DN).

        Returns
        -------
        mean, variance : arrays (n, bins) (DN, DN²)
            b + a·W, and the noise, shot noise and model discrepancy (a covariance's
            diagonal) per bin.
        """
        fixed = self.fixed_discrepancy
        if fixed is None:
            extra = (self.discrepancy * np.asarray(values["gain"])[:, None] * signal) ** 2
        elif fixed.ndim == 2:  # a covariance: its diagonal, per bin
            extra = np.diag(fixed)
        else:
            extra = fixed
        return model_moments(
            signal, values["gain"], values["baseline"], values["noise_sigma"], self.shot_factor,
            extra,
        )  # fmt: skip

    def replicate(self, signal, values, rng) -> tuple:
        """One replicated observation per row of model waveforms.

        Parameters
        ----------
        signal : array (n, bins)
            Model waveforms W.
        values : dict of arrays (n,)
            ``gain``, ``baseline`` and ``noise_sigma`` (DN).
        rng : numpy.random.Generator

        Returns
        -------
        draws : array (n, bins) (DN)
            :meth:`predictive_moments`' mean plus noise of its variance, correlated from
            bin to bin as the likelihood takes it (the read noise where it is whitened, a
            discrepancy covariance as simulated; the rest white), set to the floor or the
            digitiser maximum where the product would have set it.
        mean, variance : arrays (n, bins)
            The predictive moments they were drawn from.
        """
        mean, variance = self.predictive_moments(signal, values)
        fixed = self.fixed_discrepancy
        draws = gaussian_replicates(
            mean, variance, values["noise_sigma"], rng,
            noise_covariance=(
                None if self.whitening is None else self.whitening.covariance(mean.shape[1])
            ),
            discrepancy_covariance=fixed if fixed is not None and fixed.ndim == 2 else None,
        )  # fmt: skip
        return recorded(draws, self.data), mean, variance

    @cached_property
    def _from_basis(self):
        return conditional.from_basis_matrix(self)

    def discrepancy_given_data(self, signal, values, rng) -> np.ndarray:
        """Draws of the footprint's discrepancy d | y, one per row
        (:func:`.conditional.discrepancy_given_data`).

        Parameters
        ----------
        signal : array (n, bins)
            Model waveforms W.
        values : dict of arrays (n,)
            ``gain``, ``baseline`` and ``noise_sigma`` (DN).
        rng : numpy.random.Generator

        Returns
        -------
        array (n, bins) (DN)
            d on the window's bins; the footprint's noise-free waveform is a·W + d.

        Raises
        ------
        ValueError
            Where :attr:`conditioning_obstacle` is not None (the function checks it).
        """
        return conditional.discrepancy_given_data(self, signal, values, rng, self._from_basis)

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
        if self.following is not None:
            return self._following_log_likelihood(signal, values)
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

    @cached_property
    def _whitened_window(self):
        """L⁻¹y and L⁻¹1 (y and ones where the noise is white)."""
        samples, unit = self.data.samples, np.ones(self.data.axis.size)
        if self.whitening is None:
            return samples, unit
        return self.whitening.whiten(samples), self.whitening.whiten(unit)

    def _following_log_likelihood(self, signal, values):
        """:meth:`log_likelihood` under the covariance that follows each row's stand."""
        samples, unit = self._whitened_window
        forms = self.following.quadratic_forms(
            signal, samples, unit, values["baseline"], values["noise_sigma"]
        )
        ww, wx, xx, log_det = forms.T
        log_norm = self.data.axis.size * np.log(2.0 * np.pi) + log_det
        if self.gain_marginal is None:
            gain = np.asarray(values["gain"], float)
            chi2 = xx - 2.0 * gain * wx + gain**2 * ww
            return -0.5 * (chi2 + log_norm) + self._log_det_term, None
        with np.errstate(divide="ignore", invalid="ignore"):
            best = np.where(ww > 0, wx / ww, 0.0)
        fit = np.column_stack([ww, best, xx - best * wx, log_norm])
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
