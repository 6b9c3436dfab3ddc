"""A discrepancy covariance between bins, by rotation into its eigenbasis.

With a covariance C (bins × bins, DN²) fixed for the shot, the samples of a row are
y ~ N(b·1 + a·W, σn² I + C). Writing C = Q Λ Qᵀ, the rotated samples z = Qᵀy have the
diagonal covariance σn² I + Λ for every σn, so the per-bin kernels of :mod:`.gaussian`
apply unchanged to the rotated signal QᵀW, the rotated baseline pattern Qᵀ1 and the
eigenvalues Λ as fixed variances. Only the bins where C has variance (above
:data:`SUPPORT_FLOOR` of its largest) are rotated; the others, above the canopy and below
the ground return, stay as they are with variance σn². The shot costs one
eigendecomposition; a row costs one product with Q more (one-thread BLAS: 32 rows of 199
supported bins in 0.085 ms). Every bin must be exactly recorded (censoring
acts on single bins, not on rotated ones) and the variance must not depend on the gain
(no shot noise).
"""

from dataclasses import dataclass

import numpy as np

from ..shot import WindowData

#: Bins whose variance in C is below this fraction of its largest are left out of the
#: rotation (their covariances are smaller still, |Cᵢⱼ| ≤ √(CᵢᵢCⱼⱼ) for a covariance).
SUPPORT_FLOOR = 1e-12


def covariance_obstacle(data: WindowData, shot_factor) -> str | None:
    """Why a bin-to-bin covariance cannot enter this likelihood.

    Parameters
    ----------
    data : WindowData
    shot_factor : float (DN)

    Returns
    -------
    str or None
        The reason (shot noise, censored or saturated samples), or None if it can.
    """
    if shot_factor > 0:
        return "shot noise makes the variance depend on the gain"
    if not np.all(data.exact):
        return "the window holds censored or saturated samples"
    return None


@dataclass(frozen=True)
class Rotation:
    """The eigenbasis of a discrepancy covariance and the shot's samples in it.

    Attributes
    ----------
    kept, rotated : array of int
        Bins left as they are, and bins whose covariance is rotated (the support).
    basis : array (len(rotated), len(rotated))
        Q, orthonormal eigenvectors (columns) of C on its support.
    variances : array (bins,) (DN²)
        0 for the kept bins, then Λ, the eigenvalues (≥ 0).
    data : WindowData
        The kept samples, then Qᵀy on the support; all exactly recorded.
    unit : array (bins,)
        The baseline's pattern in the same order: ones, then Qᵀ1.
    """

    kept: np.ndarray
    rotated: np.ndarray
    basis: np.ndarray
    variances: np.ndarray
    data: WindowData
    unit: np.ndarray

    @classmethod
    def of(cls, covariance, data: WindowData, unit=None) -> "Rotation":
        """The rotation of a discrepancy covariance over a window.

        Parameters
        ----------
        covariance : array (bins, bins) (DN²)
        data : WindowData
        unit : array (bins,), optional
            The baseline's pattern over the window's bins, ones by default (the whitened
            ones where correlated noise was whitened first, :mod:`.ar_noise`).

        Returns
        -------
        Rotation

        Raises
        ------
        ValueError
            For a covariance of another shape, not finite, not symmetric or not positive
            semi-definite, or a window with censored or saturated samples.
        """
        covariance = np.asarray(covariance, float)
        bins = data.axis.size
        if covariance.shape != (bins, bins):
            raise ValueError(
                f"the discrepancy covariance must be {bins} × {bins} (the window's bins), "
                f"got {covariance.shape}"
            )
        if not np.all(np.isfinite(covariance)):
            raise ValueError("the discrepancy covariance holds NaN or infinite values")
        if not np.allclose(covariance, covariance.T, rtol=1e-10, atol=0.0):
            raise ValueError("the discrepancy covariance is not symmetric")
        obstacle = covariance_obstacle(data, 0.0)
        if obstacle is not None:
            raise ValueError(f"a discrepancy covariance cannot be used: {obstacle}")
        diagonal = np.diag(covariance)
        if diagonal.min() < -1e-8 * np.abs(diagonal).max():
            raise ValueError("the discrepancy covariance is not positive semi-definite")
        support = diagonal > SUPPORT_FLOOR * max(diagonal.max(), 0.0)
        kept, rotated = np.flatnonzero(~support), np.flatnonzero(support)
        variances, basis = np.linalg.eigh(covariance[np.ix_(rotated, rotated)])
        if variances.size and variances.min() < -1e-8 * variances.max():
            raise ValueError("the discrepancy covariance is not positive semi-definite")
        order = np.concatenate([kept, rotated])
        samples = np.concatenate([data.samples[kept], data.samples[rotated] @ basis])
        flat = WindowData(
            axis=data.axis[order],  # kept bins, then eigen-directions of the support
            samples=samples,
            censored=np.zeros(bins, bool),
            saturated=np.zeros(bins, bool),
        )
        unit = np.ones(bins) if unit is None else np.asarray(unit, float)
        unit = np.concatenate([unit[kept], unit[rotated] @ basis])
        variances = np.concatenate([np.zeros(kept.size), np.clip(variances, 0.0, None)])
        return cls(kept, rotated, basis, variances, flat, unit)

    def rotate(self, signal) -> np.ndarray:
        """Rows of model waveforms in the rotated order of :attr:`data`.

        Parameters
        ----------
        signal : array (n, bins)

        Returns
        -------
        array (n, bins)
            The kept bins as they are, then the rotated bins times Q. One BLAS product;
            :func:`lidarinv.inference.invert.invert_shot` holds BLAS to one thread (a threaded
            product of this size stalls beside other work).
        """
        signal = np.asarray(signal, float)
        out = np.empty((signal.shape[0], self.kept.size + self.rotated.size))
        out[:, : self.kept.size] = signal[:, self.kept]
        out[:, self.kept.size :] = signal[:, self.rotated] @ self.basis
        return out
