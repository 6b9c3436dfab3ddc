"""A simulated discrepancy covariance that follows each row's own stand.

The realisation covariance (:mod:`lidarinv.inference.passes.realisations`) is simulated
around the pilot MAP and fixed for the shot. A row whose stand has no crowns where the
pilot had a sparse upper storey then still finds the shot's return there a likely
departure, so the sampler may drop that storey and leave its return to the discrepancy.
Here each row's covariance is the pilot's, scaled bin by bin by the row's own expected
signal: the spread of a Poisson stand's return grows with its mean, and a row that puts
no crown in a bin puts no spread there either,

    Σ(θ) = σn²·Σ_AR + diag(f) + S·[(1 − γ)·V·Vᵀ + diag(c)]·S,  S = diag(√r),
    r_j = clip((W_j·ΣW°/ΣW + ε) / (W°_j + ε), 0, r_max),

W the row's model waveform, W° the pilot's, W rescaled to W°'s total so that the scale
follows where the return lies and not how bright it is (a brighter stand's spread in
DN is the gain's to carry, and scaling by brightness biased the marginalised gain: the
limitations page gives the calibration), ε = :data:`SIGNAL_FLOOR` of W°'s largest
value, V the leading components of the realisation residuals, c the residuals' variance
outside them and γ the shrinkage (:func:`.passes.realisations.discrepancy_covariance`),
f the instrument model's error (fixed for the shot) and Σ_AR the read noise's
correlation (:mod:`.ar_noise`). Whitened by the AR noise's L⁻¹, the diagonal part is a
band matrix of the AR order's width and the rest has rank k, so a row costs one band
Cholesky factor and a k × k one (Woodbury), not a dense factorisation of every bin.
"""

import math
from dataclasses import dataclass

import numpy as np

from forward.backends import jit

#: ε of r_j, as a fraction of the pilot's largest model signal.
SIGNAL_FLOOR = 1e-3
#: The largest scale r_j of a bin's variance.
LARGEST_SCALE = 4.0
#: The share of the residuals' second moment the leading components V keep.
KEPT_SHARE = 0.999


@dataclass(frozen=True)
class FollowingCovariance:
    """The parts of Σ(θ) fixed for the shot.

    Attributes
    ----------
    pilot_signal : array (bins,) (apparent reflectance per bin)
        W°, the model waveform of the pilot MAP the residuals were simulated about.
    components : array (bins, k) (DN)
        √(1 − γ)·V, the residuals' leading components.
    remainder : array (bins,) (DN²)
        c, γ times the residuals' variance plus (1 − γ) times what the components leave
        out of it.
    fixed : array (bins,) (DN²)
        f, the instrument model's error (not scaled).
    whitening : array (bins, p + 1)
        L⁻¹'s band: ``whitening[j, t]`` = (L⁻¹)_{j, j−t}; one column for white noise.
    """

    pilot_signal: np.ndarray
    components: np.ndarray
    remainder: np.ndarray
    fixed: np.ndarray
    whitening: np.ndarray

    @classmethod
    def of(cls, residuals, shrinkage, pilot_signal, fixed=None, noise=None,
           kept_share=KEPT_SHARE) -> "FollowingCovariance":  # fmt: skip
        """The covariance's fixed parts from the realisation residuals.

        Parameters
        ----------
        residuals : array (K, bins) (DN)
            dᵢ of :func:`.passes.realisations.realisation_residuals`.
        shrinkage : float
            γ.
        pilot_signal : array (bins,)
            W°.
        fixed : array (bins,) (DN²), optional
            f; zeros by default.
        noise : AutoregressiveNoise, optional
            The read noise's correlation; white by default.
        kept_share : float
            Share of Σ dᵢdᵢᵀ/K's trace the components keep.

        Returns
        -------
        FollowingCovariance
        """
        residuals = np.asarray(residuals, float)
        count, bins = residuals.shape
        if count < 2 or not np.all(np.isfinite(residuals)):
            raise ValueError("the following covariance needs ≥ 2 finite realisation residuals")
        pilot_signal = np.asarray(pilot_signal, float)
        if pilot_signal.shape != (bins,):
            raise ValueError(f"the pilot's signal must have {bins} bins, got {pilot_signal.shape}")
        _, singular, rows = np.linalg.svd(residuals / math.sqrt(count), full_matrices=False)
        share = np.cumsum(singular**2) / max(np.sum(singular**2), np.finfo(float).tiny)
        k = int(min(np.searchsorted(share, kept_share) + 1, singular.size))
        leading = rows[:k].T * singular[:k]  # V, bins × k
        variance = np.sum(residuals**2, axis=0) / count
        left_out = np.clip(variance - np.sum(leading**2, axis=1), 0.0, None)
        remainder = shrinkage * variance + (1.0 - shrinkage) * left_out
        fixed = np.zeros(bins) if fixed is None else np.asarray(fixed, float)
        band = np.ones((bins, 1))
        if noise is not None and noise.order > 0:
            dense = noise.whiten(np.eye(bins)).T  # L⁻¹ (whiten(X) = X·L⁻ᵀ)
            band = np.zeros((bins, noise.order + 1))
            for t in range(noise.order + 1):
                band[t:, t] = np.diagonal(dense, offset=-t)
        return cls(pilot_signal, math.sqrt(1.0 - shrinkage) * leading, remainder, fixed, band)

    @property
    def rank(self) -> int:
        """k, the components kept."""
        return self.components.shape[1]

    def scales(self, signal) -> np.ndarray:
        """r of each row (n, bins): where its model signal lies against where the pilot's
        does, each taken at the pilot's total (:func:`signal_shares`)."""
        signal = np.asarray(signal, float)
        floor = SIGNAL_FLOOR * max(float(np.max(self.pilot_signal)), 0.0)
        if floor <= 0.0:
            return np.ones_like(signal)
        ratio = (signal_shares(signal, self.pilot_signal) + floor) / (self.pilot_signal + floor)
        return np.clip(ratio, 0.0, LARGEST_SCALE)

    def covariance(self, signal) -> np.ndarray:
        """The discrepancy part of Σ(θ) for one row's model waveform, dense (bins × bins)
        (DN²): the form the tests check the compiled kernel against."""
        scale = np.sqrt(self.scales(np.asarray(signal, float)[None, :])[0])
        low = scale[:, None] * self.components
        return low @ low.T + np.diag(scale**2 * self.remainder + self.fixed)

    def quadratic_forms(self, signal, whitened_samples, whitened_unit, baseline,
                        noise_sigma) -> np.ndarray:  # fmt: skip
        """Per row, the Gaussian forms of W and y − b·1 under Σ(θ) (compiled).

        Parameters
        ----------
        signal : array (n, bins)
            W, on the window's bins.
        whitened_samples, whitened_unit : array (bins,)
            L⁻¹y and L⁻¹1.
        baseline, noise_sigma : array (n,) (DN)

        Returns
        -------
        array (n, 4)
            WᵀΣ⁻¹W, WᵀΣ⁻¹x, xᵀΣ⁻¹x (x = y − b·1) and log det of the whitened Σ
            (L⁻¹ΣL⁻ᵀ).
        """
        signal = np.ascontiguousarray(signal, dtype=np.float64)
        return _quadratic_forms(
            signal, self.scales(signal), np.ascontiguousarray(self.components),
            self.remainder, self.fixed, np.ascontiguousarray(self.whitening),
            np.asarray(whitened_samples, float), np.asarray(whitened_unit, float),
            np.ascontiguousarray(baseline, dtype=np.float64),
            np.ascontiguousarray(noise_sigma, dtype=np.float64),
        )  # fmt: skip


def signal_shares(signal, pilot_signal) -> np.ndarray:
    """Each row's model signal rescaled to the pilot's total: where its return lies, not
    how bright it is.

    Parameters
    ----------
    signal : array (n, bins) (apparent reflectance per bin)
        W of each row.
    pilot_signal : array (bins,) (apparent reflectance per bin)
        W°.

    Returns
    -------
    array (n, bins)
        W·ΣW°/ΣW; zeros for a row without signal. A brighter or fainter stand of the
        same shape (reflectance, gain) keeps the pilot's spread: only moving its return
        between heights moves the spread with it.
    """
    totals = np.sum(signal, axis=-1, keepdims=True)
    safe = np.where(totals > 0.0, totals, 1.0)
    return np.where(totals > 0.0, signal * (float(np.sum(pilot_signal)) / safe), 0.0)


@jit
def _quadratic_forms(signal, scales, components, remainder, fixed, band, y_w, unit_w, baseline,
                     noise_sigma):  # fmt: skip
    n, bins = signal.shape
    k = components.shape[1]
    p = band.shape[1] - 1
    out = np.empty((n, 4))
    diag = np.empty(bins)
    chol = np.zeros((bins, p + 1))  # the whitened diagonal part's band Cholesky factor
    inverse = np.empty(bins)  # 1 / its diagonal
    raw = np.empty((bins, k + 1))
    cols = np.zeros((bins, k + 2))  # L⁻¹ of S·V, W and x, then the factor's forward solve
    for row in range(n):
        s2 = noise_sigma[row] ** 2
        for j in range(bins):
            r = scales[row, j]
            diag[j] = fixed[j] + r * remainder[j]
            root = math.sqrt(r)
            for m in range(k):
                raw[j, m] = root * components[j, m]
            raw[j, k] = signal[row, j]
        # whiten the columns (L⁻¹ is lower triangular with p sub-diagonals)
        for j in range(bins):
            for m in range(k + 1):
                cols[j, m] = band[j, 0] * raw[j, m]
            for t in range(1, min(p, j) + 1):
                for m in range(k + 1):
                    cols[j, m] += band[j, t] * raw[j - t, m]
            cols[j, k + 1] = y_w[j] - baseline[row] * unit_w[j]
        # A = σn²·I + L⁻¹·diag(e)·L⁻ᵀ, band p; its Cholesky factor, band by band
        log_det = 0.0
        for j in range(bins):
            for d in range(min(p, j), -1, -1):  # farthest first: the diagonal needs the rest
                i = j - d  # the entry A[j, i]
                value = s2 if d == 0 else 0.0
                for t in range(d, min(p, j) + 1):
                    value += band[j, t] * diag[j - t] * band[i, t - d]
                for t in range(1, p - d + 1):  # minus Σ_m chol[j, m]·chol[i, m], m < i
                    if i - t < 0:
                        break
                    value -= chol[j, d + t] * chol[i, t]
                if d == 0:
                    chol[j, 0] = math.sqrt(value)
                    inverse[j] = 1.0 / chol[j, 0]
                    log_det += 2.0 * math.log(chol[j, 0])
                else:
                    chol[j, d] = value * inverse[i]
            # forward solve of row j: cols ← chol⁻¹·cols
            for d in range(1, min(p, j) + 1):
                for m in range(k + 2):
                    cols[j, m] -= chol[j, d] * cols[j - d, m]
            for m in range(k + 2):
                cols[j, m] *= inverse[j]
        # Woodbury: M = I + ŨᵀŨ, Ũᵀ·[w̃, x̃] and [w̃, x̃]ᵀ[w̃, x̃], by BLAS
        products = np.dot(cols.T, cols)  # (k + 2)²
        gram = products[:k, :k].copy()
        for a in range(k):
            gram[a, a] += 1.0
        factor = np.linalg.cholesky(gram)
        for a in range(k):
            log_det += 2.0 * math.log(factor[a, a])
        z = np.empty((k, 2))
        for v in range(2):
            for a in range(k):
                total = products[a, k + v]
                for m in range(a):
                    total -= factor[a, m] * z[m, v]
                z[a, v] = total / factor[a, a]
        ww, wx, xx = products[k, k], products[k, k + 1], products[k + 1, k + 1]
        for a in range(k):
            ww -= z[a, 0] * z[a, 0]
            wx -= z[a, 0] * z[a, 1]
            xx -= z[a, 1] * z[a, 1]
        out[row, 0], out[row, 1], out[row, 2], out[row, 3] = ww, wx, xx, log_det
    return out
