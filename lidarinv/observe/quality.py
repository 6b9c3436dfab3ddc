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
    """
    if not (total_energy > 0 and smallest_ground_energy >= 0):
        return float("nan")
    fraction = min(smallest_ground_energy / total_energy, 1.0)
    return float((1.0 - fraction) / (1.0 + fraction * (rho_ratio - 1.0)))
