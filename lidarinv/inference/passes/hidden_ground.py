"""A warning for shots whose lowest return may not be the ground's.

The ground prior is centred on the lowest significant mode of the waveform
(:func:`lidarinv.observe.ground.find_ground`). Under a closed canopy that mode may be the
base of the crowns, the ground's own return lost in the noise below it; the posterior then
puts the ground at the crown base, and the heights come out short by the depth of the
hidden part. A ground return has a width the model bounds: the pulse, broadened at most as
far as the broadening prior allows, then smoothed as the analysis smooths. A lowest mode
whose lower flank is wider than that widest ground return holds vegetation below its
peak, and the ground may lie lower still; or the terrain within the footprint is steeper
or rougher than the broadening prior allows. The inversion keeps the ground at the mode (a
ground prior that reached down by a canopy's depth let a lone ground peak on sloped
terrain turn into a tall closed canopy) and says so in the result's flags.
"""

import numpy as np

from lidarinv.observe.ground import HALF_MAXIMUM_PER_SIGMA, lower_flank_width
from lidarinv.observe.ground_return import DENSITY_STEP_M, broadened_densities

from ..shot import BROADENING_UPPER_M

#: Bins by which the measured flank may exceed the widest ground return's and still be
#: taken as a ground return: the measurement counts whole bins to the half maximum (one
#: bin), and noise moves the crossing by about another.
WIDTH_TOLERANCE_BINS = 2.0

#: How the result's flag begins.
HIDDEN_GROUND_FLAG = "ground may be hidden"


def widest_ground_flank_m(pulse, broadening_upper_m: float, smoothing_m: float) -> float:
    """Lower-flank width (m, as a Gaussian σ) of the widest ground return the model allows.

    Parameters
    ----------
    pulse : GaussianPulse or MeasuredPulse
        The shot's pulse (peak at offset 0).
    broadening_upper_m : float (m)
        The largest broadening the ground return may have (0 where the pulse is the whole
        response).
    smoothing_m : float (m)
        σ of the analysis' smoothing.

    Returns
    -------
    float (m)
        The distance from the return's peak down to where it falls to half its maximum on
        the lower side, over √(2 ln 2), as :func:`lidarinv.observe.ground.find_ground`
        measures a mode.
    """
    width = float(np.hypot(broadening_upper_m, smoothing_m))
    _, densities, _ = broadened_densities(pulse, [width])
    density = densities[0]
    return lower_flank_width(density, int(np.argmax(density))) * DENSITY_STEP_M


def hidden_ground_note(shot) -> str | None:
    """The result's flag where the lowest mode is wider below its peak than any ground
    return the model allows (broadened up to the broadening prior's upper end where the
    shot's transmitted waveform is its pulse, not at all otherwise); None where it is not.

    Parameters
    ----------
    shot : lidarinv.inference.shot.Shot
        With the analysis' ``ground_width`` (m) and ``smoothing_bins``.

    Returns
    -------
    str or None
    """
    analysis, obs = shot.analysis, shot.observation
    width = float(getattr(analysis, "ground_width", np.nan))
    if not np.isfinite(width):
        return None
    smoothing_m = analysis.smoothing_bins * obs.bin_size
    upper = BROADENING_UPPER_M if shot.has_transmitted_pulse else 0.0
    widest = widest_ground_flank_m(shot.instrument.pulse, upper, smoothing_m)
    if width <= widest + WIDTH_TOLERANCE_BINS * obs.bin_size / HALF_MAXIMUM_PER_SIGMA:
        return None
    return (
        f"{HIDDEN_GROUND_FLAG}: the lowest return ({analysis.ground:.2f} m) spreads "
        f"{width:.2f} m (σ) below its peak, more than a ground return can ({widest:.2f} m): "
        "the base of a closed canopy over a ground lost in the noise (the ground then lies "
        "lower and the heights are short), or terrain steeper or rougher than the "
        "broadening prior allows"
    )
