"""Shot quality: clipped samples without a saturation flag, and sensitivity."""

import numpy as np

#: Consecutive samples at the waveform's maximum that mark a clipped return.
PLATEAU_SAMPLES = 3


def clipped_plateau(samples, min_samples: int = PLATEAU_SAMPLES) -> bool:
    """True when the waveform's maximum is held by ``min_samples`` or more consecutive
    samples: the digitiser clipped the return although the file gives no saturation level.
    """
    samples = np.asarray(samples, float)
    at_max = samples == samples.max()
    if at_max.sum() < min_samples:
        return False
    run = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], at_max.view(np.int8), [0]]))))
    return bool(run[::2].max() >= min_samples)


def sensitivity(smallest_ground_energy: float, total_energy: float, rho_ratio: float) -> float:
    """The largest canopy cover under which a shot would still detect its ground.

    With ρv/ρg = r, a stand of cover c returns a fraction f = (1 − c) / (c·r + 1 − c) of
    its energy from the ground. The weakest detectable ground return, a fraction
    f = smallest_ground_energy / total_energy of the shot's energy, sets the largest
    cover c = (1 − f) / (1 + f·(r − 1)) (the idea of GEDI L2A's ``sensitivity``).

    Parameters
    ----------
    smallest_ground_energy : float
        Energy of the weakest ground return the analysis would detect (digitiser units ×
        bins).
    total_energy : float
        Energy of the shot's return (same units).
    rho_ratio : float
        ρv/ρg.

    References
    ----------
    Hofton, M. & Blair, J. B. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI
    Transmit and Receive Waveform Processing for L1 and L2 Products*, version 1.0. NASA
    Goddard Space Flight Center, Greenbelt, MD (the beam sensitivity: the largest cover
    under which the ground would still be detected).
    """
    if not (total_energy > 0 and smallest_ground_energy >= 0):
        return float("nan")
    fraction = min(smallest_ground_energy / total_energy, 1.0)
    return float((1.0 - fraction) / (1.0 + fraction * (rho_ratio - 1.0)))


#: Status of a shot whose metrics contradict each other (never "ok").
INCONSISTENT = "inconsistent metrics"


def bare_ground_share(ground_cdf) -> float:
    """Fraction of a bare, flat ground's return that lies below its peak (½ for a
    symmetric pulse, more for a pulse with a tail)."""
    return float(ground_cdf(0.0)) if ground_cdf is not None else 0.5


def bare_ground_rh50(ground_cdf, return_fwhm_m: float) -> float:
    """RH50 of a bare, flat ground's return (m): the offset of its energy median from its
    peak (0 for a symmetric pulse, below it for a pulse with a tail)."""
    if ground_cdf is None:
        return 0.0
    offsets = np.linspace(-3.0, 3.0, 601) * return_fwhm_m
    return float(np.interp(0.5, ground_cdf(offsets), offsets))


def ground_above_most_energy(energy_below_ground, total_energy, ground_share) -> bool:
    """The energy below the ground exceeds a bare ground's share of the return by more
    than half of what remains: most of the energy that is not the ground's own lies below
    it, so the ground cannot be the lowest surface."""
    if not total_energy > 0:
        return False
    return bool(energy_below_ground > (ground_share + 0.5 * (1.0 - ground_share)) * total_energy)


def negative_rh50(rh50: float, bare_rh50: float, return_fwhm_m: float) -> bool:
    """RH50 below zero by more than a bare ground puts it, with half a return FWHM of
    allowance (noise, a sloped ground's broadening): half the energy lies below the
    ground."""
    return bool(rh50 < min(bare_rh50, 0.0) - 0.5 * return_fwhm_m)


#: RH98 of a bare, flat ground's return over its FWHM: 2.054σ / 2.355σ for a Gaussian.
BARE_RH98_PER_FWHM = 0.872


def bare_but_tall(cover: float, rh98: float, return_fwhm_m: float) -> bool:
    """Cover zero (no canopy energy at all) while RH98 lies above three times what a bare
    ground's return reaches (:data:`BARE_RH98_PER_FWHM` of its FWHM): the energy above the
    ground is then canopy, and the two metrics cannot both hold."""
    return bool(cover <= 0.0 and rh98 > 3.0 * BARE_RH98_PER_FWHM * return_fwhm_m)


def contradictions(
    *, energy_below_ground, total_energy, rh, cover, return_fwhm_m, ground_cdf=None
) -> list:
    """Names of the checks a shot's metrics fail (empty when they agree).

    Parameters
    ----------
    energy_below_ground, total_energy : float (DN × bins)
        Energy above the noise below the ground, and in the whole return.
    rh : array (m) or None
        RH0 … RH100.
    cover : float
        Direct cover.
    return_fwhm_m : float (m)
        FWHM of a flat ground's return as the analysis sees it.
    ground_cdf : callable, optional
        Fraction of a flat ground's return below an offset from its peak
        (:func:`lidarinv.observe.instrument.ground_return_cdf`); default symmetric.
    """
    share = bare_ground_share(ground_cdf)
    checks = {
        "ground above most energy": ground_above_most_energy(
            energy_below_ground, total_energy, share
        ),
        "negative RH50": rh is not None
        and negative_rh50(rh[50], bare_ground_rh50(ground_cdf, return_fwhm_m), return_fwhm_m),
        "cover 0 with tall RH98": rh is not None and bare_but_tall(cover, rh[98], return_fwhm_m),
    }
    return [name for name, failed in checks.items() if failed]
