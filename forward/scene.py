"""Ground plane, the uniform understory layer, and a scene: a stand with the instrument
and footprints it is seen with."""

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Ground:
    """A Lambertian ground plane through z = 0 at the beam centre.

    Parameters
    ----------
    reflectance : float
        Effective backscatter reflectance ρg.
    slope_deg : float (degrees)
        Slope of the plane; 0 for flat ground.
    aspect_deg : float (degrees)
        Direction of steepest ascent, counter-clockwise from +x.
    """

    reflectance: float = 0.3
    slope_deg: float = 0.0
    aspect_deg: float = 0.0

    def __post_init__(self):
        if not np.isfinite(self.reflectance) or self.reflectance < 0:
            raise ValueError(f"ground reflectance must be finite and ≥ 0, got {self.reflectance}")
        if not 0.0 <= self.slope_deg < 80.0:
            raise ValueError(f"ground slope must lie in [0, 80) degrees, got {self.slope_deg}")
        if not np.isfinite(self.aspect_deg):
            raise ValueError(f"ground aspect must be finite, got {self.aspect_deg} degrees")

    @property
    def is_flat(self) -> bool:
        return self.slope_deg == 0.0

    @property
    def gradient(self) -> tuple[float, float]:
        """(∂z/∂x, ∂z/∂y) of the plane (m/m)."""
        if self.is_flat:
            return 0.0, 0.0
        tangent = float(np.tan(np.radians(self.slope_deg)))
        aspect = np.radians(self.aspect_deg)
        return tangent * float(np.cos(aspect)), tangent * float(np.sin(aspect))

    def elevation(self, dx, dy):
        """Ground height at offsets from the beam centre.

        Parameters
        ----------
        dx, dy : float or array (m)

        Returns
        -------
        float or array (m)
            tan(slope)·(cos(aspect)·dx + sin(aspect)·dy); zeros on flat ground.
        """
        if self.is_flat:
            return np.zeros(np.broadcast(dx, dy).shape)
        gx, gy = self.gradient
        return gx * np.asarray(dx) + gy * np.asarray(dy)


@dataclass(frozen=True)
class UniformUnderstory:
    """A horizontally uniform foliage layer from the ground to ``height``.

    Parameters
    ----------
    height : float (m)
        Top of the layer.
    lai : float (m²/m²)
        One-sided leaf area index of the layer.
    """

    height: float
    lai: float

    def __post_init__(self):
        if not (np.isfinite(self.height) and self.height > 0):
            raise ValueError(f"understory height must be positive, got {self.height} m")
        if not (np.isfinite(self.lai) and self.lai >= 0):
            raise ValueError(f"understory LAI must be finite and ≥ 0, got {self.lai}")

    @property
    def favd(self) -> float:
        """Foliage area volume density of the layer (m²/m³)."""
        return self.lai / self.height


@dataclass(frozen=True)
class ExampleScene:
    """A stand with the instrument and footprints it is meant to be seen with.

    Attributes
    ----------
    stand : forward.stand.Stand
    instrument : forward.instrument.Instrument
    centers : array (n, 2) (m)
        Footprint centres in stand coordinates.
    ground : Ground
    canopy_reflectance : float
        ρv.
    description : str
    """

    stand: object
    instrument: object
    centers: np.ndarray
    ground: Ground = field(default_factory=Ground)
    canopy_reflectance: float = 0.45
    description: str = ""
