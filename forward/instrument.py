"""Instrument: pulse, digitiser, footprint and the viewing-geometry constants."""

from dataclasses import dataclass, replace

import numpy as np

from .constants import SPEED_OF_LIGHT_M_PER_NS, ns_to_height
from .footprint import gaussian_footprint_weight
from .pulse import GaussianPulse, MeasuredPulse


@dataclass(frozen=True)
class Instrument:
    """A nadir-looking waveform lidar.

    Parameters
    ----------
    pulse : GaussianPulse or MeasuredPulse
        Transmitted pulse shape.
    bin_ns : float (ns)
        Digitiser bin duration Δt; the bin height is Δz = c·Δt/2.
    footprint_sigma_m : float (m)
        Standard deviation σf of the Gaussian across-beam intensity. The 1/e² diameter is
        D = 4σf.
    leaf_projection : float
        Ross–Nilson G function (0.5 for a spherical leaf angle distribution).
    clumping : float
        Clumping index Ω (1 for random foliage).
    hotspot_k : float
        Hot-spot exponent k in [1, 2]: 1 for a complete hot spot (lidar), 2 for two-way
        turbid-medium attenuation.
    name : str
        Label stored with outputs.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II, Eqs. (1)–(3): the bidirectional
    gap probability with the hot-spot factor).
    Kuusk, A. (1991). The hot spot effect in plant canopy reflectance. In R. Myneni & J.
    Ross (eds), *Photon–Vegetation Interactions*, Springer, 139–159.
    """

    pulse: object
    bin_ns: float
    footprint_sigma_m: float
    leaf_projection: float = 0.5
    clumping: float = 1.0
    hotspot_k: float = 1.0
    name: str = "custom"

    def __post_init__(self):
        checks = {
            "bin_ns": self.bin_ns,
            "footprint_sigma_m": self.footprint_sigma_m,
            "leaf_projection": self.leaf_projection,
            "clumping": self.clumping,
        }
        for label, value in checks.items():
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"instrument {label} must be positive and finite, got {value}")
        if not 1.0 <= self.hotspot_k <= 2.0:
            raise ValueError(f"hot-spot exponent k must lie in [1, 2], got {self.hotspot_k}")
        if not isinstance(self.pulse, (GaussianPulse, MeasuredPulse)):
            raise TypeError("pulse must be a GaussianPulse or a MeasuredPulse")

    @property
    def bin_height(self) -> float:
        """Digitiser bin height Δz (m)."""
        return ns_to_height(self.bin_ns)

    @property
    def footprint_diameter_m(self) -> float:
        """1/e² intensity diameter D = 4σf (m)."""
        return 4.0 * self.footprint_sigma_m

    @property
    def extinction_per_favd(self) -> float:
        """k·G·Ω: optical depth per unit foliage area (m²/m²)."""
        return self.hotspot_k * self.leaf_projection * self.clumping

    @property
    def footprint_effective_area_m2(self) -> float:
        """Effective area (∫w)²/∫w² = 4πσf² (m²) of the Gaussian footprint: the area of a
        uniform footprint whose mean over a random field has the same variance."""
        return 4.0 * np.pi * float(self.footprint_sigma_m) ** 2

    def footprint_weight(self, squared_distance):
        """The footprint's weight at squared distance r² (m²) from the beam centre.

        Parameters
        ----------
        squared_distance : float or array (m²)

        Returns
        -------
        float or array (1/m²)
            :func:`forward.footprint.gaussian_footprint_weight` of the instrument's σf.
        """
        return gaussian_footprint_weight(squared_distance, self.footprint_sigma_m)

    def with_overrides(self, **changes) -> "Instrument":
        """A copy with fields replaced.

        Parameters
        ----------
        **changes
            Instrument fields, and ``pulse_fwhm_ns`` (a Gaussian pulse, ns) or
            ``footprint_diameter_m`` (the 1/e² diameter 4σf, m); None values are ignored.

        Returns
        -------
        Instrument

        Raises
        ------
        TypeError
            Naming unknown settings.
        """
        if changes.get("pulse_fwhm_ns") is not None:
            changes["pulse"] = GaussianPulse(changes.pop("pulse_fwhm_ns"))
        if changes.get("footprint_diameter_m") is not None:
            changes["footprint_sigma_m"] = changes.pop("footprint_diameter_m") / 4.0
        changes = {k: v for k, v in changes.items() if v is not None}
        unknown = set(changes) - set(self.__dataclass_fields__)
        if unknown:
            raise TypeError(f"unknown instrument setting(s) {sorted(unknown)}")
        return replace(self, **changes)

    def describe(self) -> dict:
        """The instrument's settings, for stored outputs.

        Returns
        -------
        dict
        """
        return {
            "instrument": self.name,
            "bin_ns": self.bin_ns,
            "bin_height_m": self.bin_height,
            "footprint_sigma_m": self.footprint_sigma_m,
            "leaf_projection": self.leaf_projection,
            "clumping": self.clumping,
            "hotspot_k": self.hotspot_k,
            **self.pulse.describe(),
        }


#: k·G·Ω of the :class:`Instrument` defaults (a complete hot spot, spherical leaf angles,
#: random foliage), where no instrument is given.
DEFAULT_EXTINCTION_PER_FAVD = (
    Instrument.__dataclass_fields__["hotspot_k"].default
    * Instrument.__dataclass_fields__["leaf_projection"].default
    * Instrument.__dataclass_fields__["clumping"].default
)


def _slicer():
    """SLICER as simulated by Sun & Ranson (2000), Sec. V-A: 4 ns Gaussian pulse, 0.112 m
    bins (Δt = 2·0.112/c), 10 m footprints taken as the 1/e² diameter (σf = 2.5 m)."""
    return Instrument(GaussianPulse(4.0), 2 * 0.112 / SPEED_OF_LIGHT_M_PER_NS, 2.5, name="slicer")


def _lvis():
    """LVIS: 1 ns bins (physics conventions), a 10 ns pulse and a 20 m footprint as in
    Blair, Rabine & Hofton (1999, ISPRS J.) for the high-altitude configuration (σf = 5 m)."""
    return Instrument(GaussianPulse(10.0), 1.0, 5.0, name="lvis")


def _gedi():
    """GEDI: 1 ns bins, a roughly 15 ns FWHM transmit pulse and σf = 5.5 m, as used by
    Hancock et al. (2019, Earth Space Sci.) and listed in the physics conventions."""
    return Instrument(GaussianPulse(15.0), 1.0, 5.5, name="gedi")


INSTRUMENT_PRESETS = {"slicer": _slicer, "lvis": _lvis, "gedi": _gedi}


def instrument_preset(name: str, **overrides) -> Instrument:
    """A preset instrument with optional overrides.

    Parameters
    ----------
    name : str
        ``slicer``, ``lvis`` or ``gedi`` (:data:`INSTRUMENT_PRESETS`).
    **overrides
        As :meth:`Instrument.with_overrides` takes them.

    Returns
    -------
    Instrument

    Raises
    ------
    ValueError
        For an unknown preset.
    """
    try:
        factory = INSTRUMENT_PRESETS[name.lower()]
    except KeyError:
        raise ValueError(
            f"unknown instrument {name!r}; presets are {list(INSTRUMENT_PRESETS)}"
        ) from None
    return factory().with_overrides(**overrides)
