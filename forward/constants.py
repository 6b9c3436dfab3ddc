"""Physical constants and unit conversions shared by the forward model."""

import math

#: Speed of light in metres per nanosecond.
SPEED_OF_LIGHT_M_PER_NS = 0.299792458

#: Ratio of a Gaussian's full width at half maximum to its standard deviation, 2·sqrt(2 ln 2).
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))


def ns_to_height(duration_ns):
    """Height difference spanned by a two-way delay.

    Parameters
    ----------
    duration_ns : float or array (ns)

    Returns
    -------
    float or array (m)
        z = c·t/2.
    """
    return duration_ns * SPEED_OF_LIGHT_M_PER_NS / 2.0


def height_to_ns(height_m):
    """Two-way delay of a height difference.

    Parameters
    ----------
    height_m : float or array (m)

    Returns
    -------
    float or array (ns)
        t = 2·z/c.
    """
    return 2.0 * height_m / SPEED_OF_LIGHT_M_PER_NS
