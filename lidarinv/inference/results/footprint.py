"""What a footprint holds, beside its tallest stem: the probability that it holds no stem
at all, and whether its own waveform shows anything above its ground's return."""

import numpy as np

from lidarinv.observe.instrument import ground_return_cdf

from ..model.tallest_stem import disc_area
from ..problem import InversionProblem

#: Derived quantity: per sample, the probability that no stem stands within the footprint;
#: its posterior mean is the probability that the footprint holds no tree.
FOOTPRINT_NO_STEM = "footprint_no_stem_probability"


#: Derived quantity: per sample, 1 where the footprint's own waveform holds nothing above its
#: ground's return (its RH98 no higher than a bare ground's), else 0 (NaN without an RH98).
FOOTPRINT_BARE = "footprint_bare"
#: Broadenings on which a bare ground's RH98 is computed, then interpolated per sample.
_BROADENING_GRID = 24


def bare_ground_rh98(pulse, broadening_m, bin_m) -> np.ndarray:
    """RH98 of a bare ground: the height above a flat ground's return peak below which 98 %
    of that return lies, for the pulse widened by each sample's broadening σ, plus one bin
    (an RH spreads each bin's energy over the bin).

    Parameters
    ----------
    pulse : GaussianPulse or MeasuredPulse
    broadening_m : array (n,) (m)
    bin_m : float (m)

    Returns
    -------
    array (n,) (m)
    """
    broadening = np.asarray(broadening_m, float)
    finite = broadening[np.isfinite(broadening)]
    if not finite.size:
        return np.full(broadening.shape, np.nan)
    grid = np.linspace(finite.min(), finite.max(), _BROADENING_GRID)
    low, high = pulse.support(1e-6)
    heights = []
    for sigma in np.unique(grid):
        offsets = np.linspace(low - 6.0 * sigma, high + 6.0 * sigma, 4001)
        cumulative = ground_return_cdf(pulse, float(sigma))(offsets)
        heights.append(float(np.interp(0.98, cumulative, offsets)))
    return np.interp(broadening, np.unique(grid), heights) + float(bin_m)


def footprint_bare(problem: InversionProblem, x, rh98) -> np.ndarray:
    """Whether each sample's footprint shows no return above its ground's (1) or does (0).

    Parameters
    ----------
    problem : InversionProblem
    x : array (n, ndim)
        Posterior samples (physical units).
    rh98 : array (n,) (m)
        The RH98 of each sample's footprint waveform (NaN where unknown).

    Returns
    -------
    array (n,)
        1 where the RH98 lies within a bare ground's (:func:`bare_ground_rh98`, under the
        sample's pulse broadening): what the waveform sees of the footprint is a ground
        return, whatever stems the stand may hold there; NaN where the RH98 is NaN.
    """
    values = problem.space.values(x)
    broadening = values.get("pulse_broadening", np.zeros(x.shape[0]))
    bin_m = float(problem.window.axis[1] - problem.window.axis[0])
    bare = bare_ground_rh98(problem.instrument.pulse, broadening, bin_m)
    rh98 = np.asarray(rh98, float)
    return np.where(np.isfinite(rh98), (rh98 <= bare).astype(float), np.nan)


def footprint_no_stem(problem: InversionProblem, density_per_ha) -> np.ndarray:
    """The probability that the footprint's disc holds no stem, per posterior sample.

    Parameters
    ----------
    problem : InversionProblem
    density_per_ha : array (n,) (stems/ha)

    Returns
    -------
    array (n,)
        exp(−λ·A), λ the Poisson stand's density (stems/m²) and A the area of the
        footprint's 1/e² disc (m²), the disc :func:`.collect.footprint_top_height` draws its stems
        on; 0 where the posterior conditions on the tallest stem (that stem stands).
        Averaged over the posterior it is P(no tree in the footprint | y), the weight of
        the zeros of :func:`.collect.footprint_top_height`.
    """
    if problem.log_posterior.mapping.conditioned:
        return np.zeros(np.shape(density_per_ha))
    area = disc_area(problem.instrument.footprint_sigma_m)
    return np.exp(-np.asarray(density_per_ha, float) * 1e-4 * area)
