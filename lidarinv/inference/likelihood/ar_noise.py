"""Correlated digitiser noise as a stationary autoregressive process, and its whitening.

Real digitisers filter their detector noise, so it is correlated from bin to bin with an
autocorrelation R measured on each shot's signal-free bins
(:class:`lidarinv.observe.NoiseModel`). An AR(p) process

    x_t = φ_1 x_(t−1) + … + φ_p x_(t−p) + e_t,   var(x_t) = 1,   var(e_t) = v,

fitted to R by the Yule–Walker equations, gives the noise a covariance σn²·Σ with Σ
Toeplitz, and an exact whitening: z = L⁻¹x has unit covariance, where L⁻¹ is the
Cholesky inverse of Σ's leading p × p block on the first p bins and the AR recursion,
divided by √v, on the others. A Gaussian likelihood with covariance σn²·Σ + C then becomes
one with σn²·I + L⁻¹CL⁻ᵀ for the whitened samples and model rows, which the diagonal and
rotated kernels of the likelihood already evaluate; log det Σ is a constant of the shot.

Two fits are offered. :meth:`AutoregressiveNoise.fit` is the Yule–Walker AR(p), p the
largest lag up to ``max_order`` whose partial autocorrelation lies outside ±2/√n (n the
signal-free bins). :meth:`AutoregressiveNoise.matching_integrated_time`, the one the
inversion uses, is the AR(1) with the noise's integrated autocorrelation time
τ = 1 + 2·Σ R(k), so that its spectral density at zero frequency, which sets the
information the samples carry about a waveform that is smooth at the pulse's scale, is
the measured one: φ = (τ − 1)/(τ + 1). GEDI's noise is nearly as smooth as a Gaussian
filter's output; its Yule–Walker fits are ill-conditioned and their whitening amplifies
any high-frequency misfit of the model, while the AR(1) leaves the high frequencies
noisier than they are, which errs on the side of wider posteriors.
"""

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.linalg import cholesky, solve_triangular, toeplitz

#: Largest AR order fitted.
MAX_ORDER = 8


def levinson_durbin(autocorrelation, order: int):
    """AR coefficients φ_1…φ_p, partial autocorrelations and the innovation variance of
    a unit-variance process with autocorrelation R(0…p), by the Levinson–Durbin recursion.

    References
    ----------
    Levinson, N. (1947). The Wiener (root mean square) error criterion in filter design and
    prediction. *J. Math. Phys.* 25(1–4), 261–278.
    Durbin, J. (1960). The fitting of time-series models. *Rev. Inst. Int. Statist.* 28(3),
    233–244.
    """
    r = np.asarray(autocorrelation, float)
    phi = np.zeros(0)
    partial = np.zeros(order)
    variance = 1.0
    for k in range(1, order + 1):
        reflection = (r[k] - np.dot(phi, r[k - 1 : 0 : -1])) / variance
        phi = np.concatenate([phi - reflection * phi[::-1], [reflection]])
        variance *= 1.0 - reflection**2
        partial[k - 1] = reflection
        if not variance > 1e-9:
            raise ValueError("the autocorrelation is not positive definite")
    return phi, partial, variance


def integrated_time(autocorrelation) -> float:
    """τ = 1 + 2·Σ_(k≥1) R(k), summed up to the first non-positive lag (the far lags of a
    sample autocorrelation are noise).

    References
    ----------
    Sokal, A. (1997). Monte Carlo methods in statistical mechanics: foundations and new
    algorithms. In C. DeWitt-Morette, P. Cartier & A. Folacci (eds), *Functional
    Integration: Basics and Applications*, NATO ASI Series B 361, Springer, 131–192 (the
    integrated autocorrelation time and its truncated sum).
    Goodman, J. & Weare, J. (2010). Ensemble samplers with affine invariance. *Commun. Appl.
    Math. Comput. Sci.* 5(1), 65–80.
    """
    r = np.asarray(autocorrelation, float)
    stop = np.flatnonzero(r[1:] <= 0)
    head = r[1 : 1 + stop[0]] if stop.size else r[1:]
    return float(1.0 + 2.0 * np.sum(head))


@dataclass(frozen=True)
class AutoregressiveNoise:
    """Unit-variance AR(p) noise.

    Attributes
    ----------
    coefficients : array
        φ_1 … φ_p (empty for white noise).
    innovation_variance : float
        v = var(e_t) for var(x_t) = 1.
    head_autocorrelation : array
        R(0 … p) of the process (the fitted autocorrelation at those lags).

    References
    ----------
    Yule, G. U. (1927). On a method of investigating periodicities in disturbed series, with
    special reference to Wolfer's sunspot numbers. *Phil. Trans. R. Soc. Lond. A* 226,
    267–298.
    Walker, G. (1931). On periodicity in series of related terms. *Proc. R. Soc. Lond. A*
    131(818), 518–532.
    Levinson, N. (1947). The Wiener (root mean square) error criterion in filter design and
    prediction. *J. Math. Phys.* 25(1–4), 261–278.
    Durbin, J. (1960). The fitting of time-series models. *Rev. Inst. Int. Statist.* 28(3),
    233–244.
    """

    coefficients: np.ndarray
    innovation_variance: float
    head_autocorrelation: np.ndarray

    @classmethod
    def white(cls) -> "AutoregressiveNoise":
        return cls(np.zeros(0), 1.0, np.ones(1))

    @classmethod
    def fit(
        cls, autocorrelation, n_samples: int, max_order: int = MAX_ORDER
    ) -> "AutoregressiveNoise":
        """Yule–Walker fit to a measured autocorrelation R(0, 1, …) from ``n_samples``
        signal-free bins; the order is the last significant partial autocorrelation.

        References
        ----------
        Yule, G. U. (1927). On a method of investigating periodicities in disturbed series,
        with special reference to Wolfer's sunspot numbers. *Phil. Trans. R. Soc. Lond. A*
        226, 267–298.
        Walker, G. (1931). On periodicity in series of related terms. *Proc. R. Soc. Lond.
        A* 131(818), 518–532.
        Durbin, J. (1960). The fitting of time-series models. *Rev. Inst. Int. Statist.*
        28(3), 233–244 (the recursion and the partial autocorrelations).
        """
        r = np.asarray(autocorrelation, float)
        if r.ndim != 1 or r.size == 0 or not np.all(np.isfinite(r)) or r[0] != 1.0:
            raise ValueError("an autocorrelation must be finite and start with R(0) = 1")
        if n_samples < 2:
            raise ValueError(f"need at least 2 signal-free bins, got {n_samples}")
        top = min(max_order, r.size - 1)
        while top > 0:  # the highest order the measured lags admit (a sample
            try:  # autocorrelation need not be positive definite to every order)
                _, partial, _ = levinson_durbin(r, top)
                break
            except ValueError:
                top -= 1
        if top == 0:
            return cls.white()
        significant = np.flatnonzero(np.abs(partial) > 2.0 / np.sqrt(n_samples))
        order = int(significant[-1]) + 1 if significant.size else 0
        if order == 0:
            return cls.white()
        phi, _, variance = levinson_durbin(r, order)
        return cls(phi, float(variance), r[: order + 1].copy())

    @classmethod
    def matching_integrated_time(cls, autocorrelation) -> "AutoregressiveNoise":
        """The AR(1) with the integrated autocorrelation time of a measured R(0, 1, …),
        summed up to its first non-positive lag."""
        tau = integrated_time(autocorrelation)
        phi = (tau - 1.0) / (tau + 1.0)
        if phi <= 0:
            return cls.white()
        return cls(np.array([phi]), 1.0 - phi**2, np.array([1.0, phi]))

    @classmethod
    def of_measured(cls, noise) -> "AutoregressiveNoise":
        """The noise model of a shot's measured noise: the AR(1) with its integrated
        autocorrelation time (:meth:`matching_integrated_time`); white where the noise
        came from a file's fields, which hold no autocorrelation.

        Parameters
        ----------
        noise : lidarinv.observe.NoiseModel or None

        Returns
        -------
        AutoregressiveNoise
        """
        if noise is None or noise.source != "samples":
            return cls.white()
        return cls.matching_integrated_time(noise.autocorrelation)

    @property
    def integrated_time(self) -> float:
        """τ = 1 + 2·Σ R(k) of the process (its spectral density at zero frequency)."""
        return float(1.0 / (1.0 - np.sum(self.coefficients)) ** 2 * self.innovation_variance)

    @property
    def order(self) -> int:
        return int(self.coefficients.size)

    def autocorrelation(self, n_lags: int) -> np.ndarray:
        """R(0 … n_lags − 1) of the process (the AR recursion beyond lag p)."""
        p = self.order
        out = np.zeros(max(n_lags, p + 1))
        out[: p + 1] = self.head_autocorrelation[: p + 1]
        for k in range(p + 1, out.size):
            out[k] = np.dot(self.coefficients, out[k - 1 : k - p - 1 : -1])
        return out[:n_lags]

    def covariance(self, n: int) -> np.ndarray:
        """Σ (n × n), the dense unit-variance covariance: the reference for tests."""
        return toeplitz(self.autocorrelation(n))

    def log_det(self, n: int) -> float:
        """log det Σ for ``n`` bins."""
        p = min(self.order, n)
        head = 0.0
        if p:
            head = 2.0 * np.sum(
                np.log(np.diag(cholesky(toeplitz(self.head_autocorrelation[:p]), lower=True)))
            )
        return float(head + (n - p) * np.log(self.innovation_variance))

    def whiten(self, values) -> np.ndarray:
        """L⁻¹x along the last axis: unit-covariance samples from ``values`` of covariance Σ.

        Linear, so it applies to samples and model rows alike (and to a constant
        baseline: ``whiten(ones)`` is the baseline's whitened pattern).
        """
        x = np.asarray(values, float)
        p = self.order
        if p == 0:
            return x.copy()
        n = x.shape[-1]
        out = x.copy()  # e_t = x_t − Σ φ_k x_(t−k), as p shifted products over the batch
        for k, phi in enumerate(self.coefficients[: n - 1], start=1):
            out[..., k:] -= phi * x[..., :-k]
        out /= np.sqrt(self.innovation_variance)
        head = min(p, n)
        out[..., :head] = x[..., :head] @ self._head_whitening[:head, :head].T
        return out

    @cached_property
    def _head_whitening(self) -> np.ndarray:
        """L⁻¹ of the leading p × p block of Σ (lower triangular, so that its leading
        k × k block whitens the first k < p bins too)."""
        p = self.order
        factor = cholesky(toeplitz(self.head_autocorrelation[:p]), lower=True)
        return solve_triangular(factor, np.eye(p), lower=True)
