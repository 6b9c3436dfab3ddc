"""Allometry in the form of Sun & Ranson (2000), Table II.

The paper derives tree height from DBH and crown length and crown width from height by
per-species regressions. Its coefficients are not in the text we have, so the defaults
below are our own, chosen so that the BOREAS jack pine stand has heights of 12–15 m
(paper, Sec. VI-A) and about 180 m³ (cones) / 310 m³ (ellipsoids) of crown per 10 m
footprint (Sec. V-A). Pass your own coefficients for other species.

Forms:

- height (m) = 1.3 + a · (1 − exp(−b · DBH))^c          (Chapman–Richards, DBH in cm)
- crown length (m) = p0 + p1 · height
- crown radius (m) = q0 + q1 · height
"""

from dataclasses import dataclass

import numpy as np

from .crowns import crown_radius


@dataclass(frozen=True)
class Allometry:
    """Per-species allometric coefficients (see module docstring for the forms).

    Parameters
    ----------
    height_asymptote : float (m)
        ``a``: asymptotic height above breast height.
    height_rate : float (1/cm)
        ``b``.
    height_shape : float
        ``c`` (dimensionless).
    crown_length_intercept, crown_length_slope : float (m, m/m)
    crown_radius_intercept, crown_radius_slope : float (m, m/m)

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Table II: height from DBH, crown length
    and width from height).
    Richards, F. J. (1959). A flexible growth function for empirical use. *J. Exp. Bot.*
    10(2), 290–300 (the height curve's form).
    """

    height_asymptote: float
    height_rate: float
    height_shape: float
    crown_length_intercept: float
    crown_length_slope: float
    crown_radius_intercept: float
    crown_radius_slope: float

    def height(self, dbh_cm):
        """Tree height from stem diameter.

        Parameters
        ----------
        dbh_cm : float or array (cm)
            Diameter at breast height, finite and ≥ 0.

        Returns
        -------
        float or array (m)
            h = 1.3 + a·(1 − e^{−b·DBH})^c (Chapman–Richards).

        Raises
        ------
        ValueError
            For a negative or non-finite DBH.
        """
        dbh = np.asarray(dbh_cm, float)
        if np.any(dbh < 0) or not np.all(np.isfinite(dbh)):
            raise ValueError("DBH must be finite and non-negative (cm)")
        return (
            1.3 + self.height_asymptote * (1 - np.exp(-self.height_rate * dbh)) ** self.height_shape
        )

    def crown_length(self, height_m):
        """Crown length from tree height.

        Parameters
        ----------
        height_m : float or array (m)

        Returns
        -------
        float or array (m)
            intercept + slope·h, clipped to [0, h]: never longer than the tree.
        """
        h = np.asarray(height_m, float)
        return np.clip(self.crown_length_intercept + self.crown_length_slope * h, 0.0, h)

    def crown_radius(self, height_m):
        """Crown radius from tree height.

        Parameters
        ----------
        height_m : float or array (m)

        Returns
        -------
        float or array (m)
            max(intercept + slope·h, 0).
        """
        h = np.asarray(height_m, float)
        return np.maximum(
            crown_radius(h, self.crown_radius_intercept, self.crown_radius_slope), 0.0
        )


#: Default coefficients by species. Our calibration, not the paper's numbers (see above).
SPECIES_ALLOMETRY: dict[str, Allometry] = {
    "jack pine": Allometry(15.5, 0.12, 1.4, 0.0, 0.45, 0.1, 0.095),
    "conifer": Allometry(28.0, 0.045, 1.2, 0.5, 0.55, 0.3, 0.09),
    "deciduous": Allometry(26.0, 0.05, 1.1, 0.5, 0.5, 0.6, 0.14),
}
