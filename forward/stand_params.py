"""Parameterised stands: a frozen parameter object and the height-distribution registry.

A :class:`StandParams` describes a stationary stand by a handful of numbers instead of a
stem map. Trees are a Poisson population of ``density`` stems per hectare, split into at
most two cohorts (for multi-tier stands, or a population of small understory crowns).
Each cohort has its own height distribution and crown-shape mix; crown dimensions follow
one allometry, crown length = ``crown_length_ratio``·h and crown radius
= ``crown_radius_intercept`` + ``crown_radius_slope``·h. The same object feeds
:func:`forward.realise.realise` (explicit random stands), :mod:`forward.derived` (canopy
cover, LAI, …) and :class:`forward.expected.ExpectedWaveformModel`.

Height distributions are chosen through :data:`HEIGHT_DISTRIBUTIONS`
(:mod:`forward.height_families`); every family is parameterised by two numbers, ``mean``
and ``sd`` (m), documented per family.
"""

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace

import numpy as np

from .crowns import SHAPE_NAMES, crown_radius
from .height_families import (  # noqa: F401  (re-exported: the stand's height families)
    HEIGHT_DISTRIBUTIONS,
    HeightFamily,
    height_distribution,
)

# --- the parameter object ------------------------------------------------------------


def _by_shape(value, label, missing):
    """A tuple over SHAPE_NAMES from a mapping (name → number; absent names get
    ``missing``) or from a sequence of one number per shape."""
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - set(SHAPE_NAMES))
        if unknown:
            raise ValueError(f"{label}: unknown crown shape(s) {unknown}; known {SHAPE_NAMES}")
        value = tuple(value.get(name, missing) for name in SHAPE_NAMES)
    value = tuple(float(v) for v in value)
    if len(value) != len(SHAPE_NAMES):
        raise ValueError(f"{label}: need one number per shape {SHAPE_NAMES}")
    return value


def _as_mix(value, label):
    """Normalise a shape mix (name → fraction, or one name) to a tuple over SHAPE_NAMES."""
    value = _by_shape({value: 1.0} if isinstance(value, str) else value, label, 0.0)
    if any(not np.isfinite(v) or v < 0 for v in value) or not np.isclose(sum(value), 1.0):
        raise ValueError(f"{label}: fractions must be ≥ 0 and sum to 1, got {value}")
    return value


def _as_ratio(value):
    value = _by_shape(value, "favd_ratio", 1.0)
    if any(not np.isfinite(v) or v <= 0 for v in value):
        raise ValueError(f"favd_ratio needs one positive number per shape {SHAPE_NAMES}")
    return value


@dataclass(frozen=True)
class StandParams:
    """Parameters of a stationary (Poisson) stand.

    Parameters
    ----------
    density : float (stems/ha)
        Stem density of all cohorts together.
    height_mean, height_sd : float (m)
        Height distribution of cohort 1 (see :data:`HEIGHT_DISTRIBUTIONS` for what they
        mean per family).
    height_family : str
        Key of :data:`HEIGHT_DISTRIBUTIONS`, shared by both cohorts.
    shape_mix : str or mapping or tuple
        Crown-shape fractions of cohort 1 (name → fraction, or one name).
    cohort2_fraction : float
        Fraction of stems in cohort 2 (0: a single cohort).
    cohort2_height_mean, cohort2_height_sd : float (m)
        Height distribution of cohort 2.
    cohort2_shape_mix : str or mapping or tuple, optional
        Shape fractions of cohort 2; cohort 1's mix by default.
    height_truncation : float (sd units)
        Truncation of the ``truncnorm`` family (ignored by the others).
    crown_length_ratio : float
        Crown length over tree height, in (0, 1].
    crown_radius_intercept : float (m)
    crown_radius_slope : float (m/m)
        Crown radius Rc = intercept + slope·h (m); must be positive over the heights.
    favd : float (m²/m³)
        Foliage area volume density of crowns.
    favd_ratio : mapping or tuple
        Per-shape multiplier of ``favd`` (default 1 for every shape).
    understory_height : float (m)
    understory_lai : float (m²/m²)
        Uniform understory layer from 0 to ``understory_height``; LAI 0 means none.
    canopy_reflectance : float
        ρv, effective canopy backscatter reflectance.
    ground_reflectance : float
        ρg, ground reflectance.
    """

    density: float
    height_mean: float
    height_sd: float
    height_family: str = "weibull"
    shape_mix: object = "cone"
    cohort2_fraction: float = 0.0
    cohort2_height_mean: float = 5.0
    cohort2_height_sd: float = 1.0
    cohort2_shape_mix: object = None
    height_truncation: float = 2.0
    crown_length_ratio: float = 0.5
    crown_radius_intercept: float = 0.0
    crown_radius_slope: float = 0.1
    favd: float = 0.8
    favd_ratio: object = field(default=(1.0, 1.0, 1.0, 1.0))
    understory_height: float = 1.0
    understory_lai: float = 0.0
    canopy_reflectance: float = 0.45
    ground_reflectance: float = 0.3

    def __post_init__(self):
        mix = _as_mix(self.shape_mix, "shape_mix")
        mix2 = mix if self.cohort2_shape_mix is None else _as_mix(self.cohort2_shape_mix, "cohort2")
        object.__setattr__(self, "shape_mix", mix)
        object.__setattr__(self, "cohort2_shape_mix", mix2)
        object.__setattr__(self, "favd_ratio", _as_ratio(self.favd_ratio))
        if self.height_family not in HEIGHT_DISTRIBUTIONS:
            raise ValueError(
                f"unknown height_family {self.height_family!r}; "
                f"known: {sorted(HEIGHT_DISTRIBUTIONS)}"
            )
        for name in (
            "density",
            "understory_lai",
            "canopy_reflectance",
            "ground_reflectance",
            "cohort2_fraction",
        ):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"{name} must be finite and ≥ 0, got {value}")
        for name in (
            "height_mean",
            "height_sd",
            "favd",
            "understory_height",
            "height_truncation",
            "crown_radius_slope",
        ):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be positive and finite, got {value}")
        if self.cohort2_fraction > 1:
            raise ValueError(f"cohort2_fraction must lie in [0, 1], got {self.cohort2_fraction}")
        if self.cohort2_fraction > 0:
            for name in ("cohort2_height_mean", "cohort2_height_sd"):
                value = getattr(self, name)
                if not np.isfinite(value) or value <= 0:
                    raise ValueError(f"{name} must be positive and finite, got {value}")
        if not 0 < self.crown_length_ratio <= 1:
            raise ValueError(
                f"crown_length_ratio must lie in (0, 1], got {self.crown_length_ratio}"
            )
        if not np.isfinite(self.crown_radius_intercept) or self.crown_radius_intercept < 0:
            raise ValueError(
                f"crown_radius_intercept must be finite and ≥ 0, got {self.crown_radius_intercept}"
            )
        family = HEIGHT_DISTRIBUTIONS[self.height_family]
        for mean, sd, label in self._cohort_moments():
            if not family.valid(mean, sd, self.height_truncation):
                raise ValueError(
                    f"{label}: height mean {mean} m and sd {sd} m are outside what the "
                    f"{self.height_family} family supports ({family.meaning})"
                )

    def _cohort_moments(self):
        out = [(self.height_mean, self.height_sd, "cohort 1")]
        if self.cohort2_fraction > 0:
            out.append((self.cohort2_height_mean, self.cohort2_height_sd, "cohort 2"))
        return out

    # conveniences -------------------------------------------------------------------
    @property
    def density_per_m2(self) -> float:
        """Stem density (stems/m²)."""
        return self.density / 1e4

    def cohort_laws(self):
        """The height laws of the stand's cohorts with trees.

        Returns
        -------
        list of (float, float, float, array)
            (weight, height mean (m), height sd (m), shape fractions) of each cohort with
            weight > 0, in :attr:`height_family`.
        """
        both = (
            (1 - self.cohort2_fraction, self.height_mean, self.height_sd, self.shape_mix),
            (
                self.cohort2_fraction,
                self.cohort2_height_mean,
                self.cohort2_height_sd,
                self.cohort2_shape_mix,
            ),
        )
        return [(w, mean, sd, np.asarray(mix)) for w, mean, sd, mix in both if w > 0]

    def cohorts(self):
        """The stand's cohorts with trees.

        Returns
        -------
        list of (float, scipy.stats.rv_frozen, array)
            (weight, height distribution, shape fractions) of each cohort with weight > 0.
        """
        return [
            (w, height_distribution(self.height_family, mean, sd, self.height_truncation), mix)
            for w, mean, sd, mix in self.cohort_laws()
        ]

    def favd_by_shape(self) -> np.ndarray:
        """FAVD of each shape.

        Returns
        -------
        array (m²/m³)
            FAVD times the shape's ratio, in :data:`forward.crowns.SHAPE_NAMES` order.
        """
        return self.favd * np.asarray(self.favd_ratio)

    def crown_length(self, height):
        """Crown length at tree heights.

        Parameters
        ----------
        height : float or array (m)

        Returns
        -------
        float or array (m)
            ℓ·h.
        """
        return self.crown_length_ratio * np.asarray(height, float)

    def crown_radius(self, height):
        """Crown radius at tree heights.

        Parameters
        ----------
        height : float or array (m)

        Returns
        -------
        float or array (m)
            r0 + r1·h.
        """
        h = np.asarray(height, float)
        return crown_radius(h, self.crown_radius_intercept, self.crown_radius_slope)

    def with_values(self, **changes) -> "StandParams":
        """A copy with fields replaced (validated again).

        Parameters
        ----------
        **changes
            StandParams fields.

        Returns
        -------
        StandParams
        """
        return replace(self, **changes)

    def as_dict(self) -> dict:
        """The parameters as a dict.

        Returns
        -------
        dict
            Field name → value.
        """
        return {f.name: getattr(self, f.name) for f in fields(self)}
