"""The footprint's own waveform: the model discrepancy drawn given the observation.

The likelihood takes the samples as y = b·1 + a·W + d + ε, the expected stand's waveform
a·W plus the discrepancy d ~ N(0, C) of the one arrangement of trees in the footprint,
plus read noise ε ~ N(0, σn²Σ). The footprint's noise-free waveform is a·W + d, and it is
what the observation (and a product's RH) measures: a tall crown that the stand's mean
spreads thin is all there in the footprint. Given y and a parameter row,

    d | y ~ N(C·V⁻¹·r, C − C·V⁻¹·C),   r = y − b·1 − a·W,   V = σn²Σ + C,

and in the likelihood's basis (:mod:`.ar_noise` whitening, then the rotation of
:mod:`.covariance`), where Σ becomes I and C the diagonal Λ, each component is the
scalar Wiener filter: mean λ/(σn² + λ)·r', variance λσn²/(σn² + λ). Bins where C has no
variance keep d = 0, so the noise above the canopy and below the ground never enters.
"""

import numpy as np


def conditioning_obstacle(like) -> str | None:
    """Why the discrepancy cannot be drawn given the data, or None if it can.

    Parameters
    ----------
    like : ShotLikelihood

    Returns
    -------
    str or None
        Shot noise (the variance then depends on the signal) and censored or saturated
        bins (their samples are bounds, not values) leave d | y non-Gaussian.
    """
    if like.shot_factor > 0:
        return "shot noise makes the variance depend on the signal"
    if not np.all(like.data.exact):
        return "the window holds censored or saturated samples"
    return None


def from_basis_matrix(like) -> np.ndarray | None:
    """The matrix B that takes rows back from the likelihood's basis, x = x'·B; None
    where the basis is the window's own bins.

    Parameters
    ----------
    like : ShotLikelihood

    Returns
    -------
    array (bins, bins) or None
    """
    if like.whitening is None and like.rotation is None:
        return None
    forward = like.to_basis(np.eye(like.data.axis.size))  # x' = x·forward
    return np.linalg.inv(forward)


def discrepancy_given_data(like, signal, values, rng, back=None) -> np.ndarray:
    """Draws of the footprint's discrepancy d | y, one per row.

    Parameters
    ----------
    like : ShotLikelihood
        Without a :func:`conditioning_obstacle`.
    signal : array (n, bins)
        Model waveforms W of the rows.
    values : dict of arrays (n,)
        ``gain``, ``baseline`` and ``noise_sigma`` (DN).
    rng : numpy.random.Generator
    back : array (bins, bins), optional
        :func:`from_basis_matrix` of ``like``, computed once for many calls.

    Returns
    -------
    array (n, bins) (DN)
        d on the window's bins; the footprint's noise-free waveform is a·W + d.

    Raises
    ------
    ValueError
        Where the likelihood has a :func:`conditioning_obstacle`.

    References
    ----------
    Wiener, N. (1949). *Extrapolation, Interpolation, and Smoothing of Stationary Time
    Series*. MIT Press.
    Rasmussen, C. E. & Williams, C. K. I. (2006). *Gaussian Processes for Machine Learning*.
    MIT Press, App. A.2 (conditional Gaussians).
    """
    obstacle = conditioning_obstacle(like)
    if obstacle is not None:
        raise ValueError(f"the discrepancy cannot be drawn given the data: {obstacle}")
    gain = np.asarray(values["gain"], float)[:, None]
    baseline = np.asarray(values["baseline"], float)[:, None]
    noise = np.asarray(values["noise_sigma"], float)[:, None] ** 2
    model = like.to_basis(signal)
    data, unit, fixed = like.in_basis()
    residual = data[None, :] - baseline * unit[None, :] - gain * model
    spread = fixed[None, :] + (like.discrepancy_scale * gain * model) ** 2
    total = noise + spread
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(total > 0, spread / total, 0.0)
    draws = share * residual + np.sqrt(share * noise) * rng.standard_normal(residual.shape)
    if back is None:
        back = from_basis_matrix(like)
    return draws if back is None else draws @ back
