"""The simulated waveform and everything the engine learned on the way."""

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Waveform:
    """A simulated waveform on a height axis.

    Attributes
    ----------
    heights : array (m)
        Bin-centre heights above the ground at the beam centre, ascending.
    samples : array
        Waveform samples: apparent reflectance per bin (canopy + ground); they sum to
        ``canopy_energy + ground_energy`` when the window holds the whole return.
    canopy, ground : arrays
        The canopy and ground parts of ``samples``.
    gap : array
        Footprint-mean bidirectional gap probability P̄ at the bin centres.
    crown_volume : array (m³/m² per bin)
        Footprint-weighted crown volume in each bin per unit ground area.
    foliage_area : array (m²/m² per bin)
        Footprint-weighted one-sided foliage area in each bin (crowns and understory).
    canopy_energy : float
        ρv·(1 − P̄(0)): the whole canopy return.
    ground_energy : float
        ρg·P̄(ground): the whole ground return.
    ground_gap : float
        P̄ at the ground.
    center : tuple (m)
        Beam centre (x, y) in stand coordinates.
    settings : dict
        Instrument, scene and accuracy settings used.
    """

    heights: np.ndarray
    samples: np.ndarray
    canopy: np.ndarray
    ground: np.ndarray
    gap: np.ndarray
    crown_volume: np.ndarray
    foliage_area: np.ndarray
    canopy_energy: float
    ground_energy: float
    ground_gap: float
    center: tuple = (0.0, 0.0)
    settings: dict = field(default_factory=dict)

    @property
    def bin_height(self) -> float:
        return float(self.heights[1] - self.heights[0]) if self.heights.size > 1 else np.nan

    @property
    def total_energy(self) -> float:
        """Canopy plus ground return: ρv(1 − P̄(0)) + ρg·P̄(0)."""
        return self.canopy_energy + self.ground_energy

    def crown_volume_total(self) -> float:
        """Footprint-weighted crown volume per unit ground area in the window.

        Returns
        -------
        float (m)
            The sum of ``crown_volume`` over the bins.
        """
        return float(self.crown_volume.sum())
