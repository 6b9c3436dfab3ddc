"""Accuracy settings of the explicit engine: a tolerance, and the resolution it buys.

A user states the relative L1 error of a waveform (Σ|ΔW| / ΣW against the converged
engine) that they accept; :class:`AccuracySettings` turns it into the engine's
resolution:

- Columns. The error of a grid of columns comes from the crown edges between them and
  falls as the spacing s to the power 1.5 for one crown; over the N ≈ (σf/R)² crowns
  of a footprint of σf under crowns of radius R it averages as 1/√N. So
  ε ≈ (s/R)^1.5/√N, and :meth:`AccuracySettings.column_spacing_for` solves it for s,
  s = C·ε^(2/3)·R·N^(1/3) = C·ε^(2/3)·σf^(2/3)·R^(1/3), with C measured on the stands of
  ``studies/forward_runtime_vs_error.py``. Where fewer crowns share the footprint's
  weight, N is their effective number (Σω)²/Σω² and the columns are closer.
- Crown shapes. The spacing is set by the roughest crown edge in the footprint: a
  column's path through a cone falls to zero at its edge (a kink in the path length),
  through an ellipsoid steeply, through a cylinder at once (a jump); so footprints
  under cones alone take columns :data:`EDGE_SPACING_FACTOR` times wider, up to an
  eighth of the crown radius.
- Ground. The ground return ρg·P̄(0) needs only each column's whole optical depth, but
  its relative error is larger than the waveform's where the canopy is closed (P̄(0)
  small): the ground has columns of its own, at the spacing of the same law with the
  constant :data:`GROUND_SPACING_CONSTANT` (:meth:`AccuracySettings.ground_spacing_for`),
  and the canopy returns are scaled so that the energies still add up.
- Truncation. The footprint weight left out beyond the truncation radius is a tenth of
  the tolerance (conventions, "Footprint"), and :data:`GROUND_TRUNCATION` of it for the
  ground's columns:
  the weight left out errs on the ground gap by about that weight times the gap at the
  rim over P̄(0), large where the canopy over the beam centre is closed.
- Layers. A fine layer spreads its return evenly over its thickness h; after the pulse
  that costs about (h/σz)²/200 in relative L1 (measured for GEDI and SLICER pulses), so
  the layers are made thin enough for it to stay below an eighth of the tolerance, and
  at most σz/4 thick (the rule of earlier versions, which the default tolerance meets).

The per-crown disc quadrature of earlier versions stays available: setting
``radial_nodes`` or ``angular_nodes`` selects it (``scheme == "crowns"``), with the
truncation it had (1e-3).
"""

from dataclasses import dataclass, field

import numpy as np

from ..backends import BACKENDS
from ..crowns import SHAPE_NAMES

#: Relative L1 error the default settings aim for.
DEFAULT_TOLERANCE = 3e-3

#: C in s = C·ε^(2/3)·σf^(2/3)·R^(1/3) (m^0 overall: s, σf and R in m).
SPACING_CONSTANT = 3.0

#: The same constant for the columns of the ground gap: half that of the profiles, since
#: at the profiles' spacing the ground gap's relative error reaches 1 % under closed
#: canopies, where P̄(0) is small (measured in ``studies/forward_runtime_vs_error.py``).
GROUND_SPACING_CONSTANT = 1.5

#: Truncation tolerance of the ground's columns, as a fraction of ``tolerance``: the
#: weight w left out errs on the ground gap by about w·(P at the rim)/P̄(0), which
#: approaches 0.1 % under the closed canopies of the study at w = 3e-5 (measured).
GROUND_TRUNCATION = 0.003

#: Column spacing factor of a footprint whose crowns all have this shape (the smallest
#: factor among the footprint's crowns applies). Cone edges are kinks of the path
#: length, not steep or sudden: the dense cone stands of the study meet the tolerance
#: with columns 1.4 times wider.
EDGE_SPACING_FACTOR = {"cone": 1.4, "ellipsoid": 1.0, "hemi-ellipsoid": 1.0, "cylinder": 1.0}

#: Widest spacing, as a fraction of the crown radius, that :data:`EDGE_SPACING_FACTOR`
#: may widen the columns to: a kink's error stays small only while several columns cross
#: the crown's edge (at tolerance 1e-2 the dense cone stands leave no room to widen).
EDGE_RESOLUTION = 1.0 / 8.0

#: Truncation tolerance of the per-crown quadrature (``scheme == "crowns"``).
CROWN_SCHEME_TRUNCATION = 1e-3


@dataclass(frozen=True)
class AccuracySettings:
    """Numerical settings of the explicit engine.

    Parameters
    ----------
    radial_nodes, angular_nodes : int, optional
        Select the per-crown disc quadrature of earlier versions (rings in ρ² × angles
        per crown; 4 × 8 when only one is given). Left out, the engine uses columns on a
        grid, which stay accurate where crowns overlap.
    truncation_tolerance : float, optional
        Footprint weight left out beyond the truncation radius; by default a tenth of
        ``tolerance`` (at most 1e-3; :data:`GROUND_TRUNCATION` of it for the ground's columns,
        :attr:`ground_tolerance`), or 1e-3 for the per-crown quadrature.
    vertical_oversampling : int, optional
        Fine layers per digitiser bin; by default from ``tolerance`` (layers at most
        σz/4 thick).
    pulse_tolerance : float
        Pulse area left out in each tail.
    tolerance : float
        Relative L1 error of the waveform that the resolution aims for.
    column_spacing : float (m), optional
        Column spacing at the beam centre; by default from ``tolerance``, the footprint
        size and the crowns' radii.
    backend : str
        ``"numba"`` (compiled column kernel), ``"numpy"`` (its numpy reference), or
        ``"auto"``: numba when it can be imported. Both give the same results to
        rounding.
    """

    radial_nodes: int | None = None
    angular_nodes: int | None = None
    truncation_tolerance: float | None = None
    vertical_oversampling: int | None = None
    pulse_tolerance: float = 1e-9
    tolerance: float = field(default=DEFAULT_TOLERANCE, kw_only=True)
    column_spacing: float | None = field(default=None, kw_only=True)
    backend: str = field(default="auto", kw_only=True)

    def __post_init__(self):
        for name in ("radial_nodes", "angular_nodes", "vertical_oversampling"):
            value = getattr(self, name)
            if value is not None and (not isinstance(value, (int, np.integer)) or value < 1):
                raise ValueError(f"{name} must be None or an integer ≥ 1, got {value!r}")
        t = self.truncation_tolerance
        if t is not None and not 0.0 < t < 1.0:
            raise ValueError(f"truncation_tolerance must lie in (0, 1), got {t}")
        if not 0.0 < self.pulse_tolerance < 0.5:
            raise ValueError(
                f"pulse_tolerance (pulse area left out per tail) must lie in (0, 0.5), "
                f"got {self.pulse_tolerance}"
            )
        if not (isinstance(self.tolerance, (int, float)) and 0.0 < self.tolerance < 0.5):
            raise ValueError(
                f"tolerance (relative L1 error) must lie in (0, 0.5), got {self.tolerance!r}"
            )
        s = self.column_spacing
        if s is not None and not (np.isfinite(s) and s > 0):
            raise ValueError(f"column_spacing must be None or positive (m), got {s!r}")
        if self.backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {self.backend!r}")

    @property
    def scheme(self) -> str:
        """``"columns"`` (grid of columns) or ``"crowns"`` (per-crown quadrature)."""
        legacy = self.radial_nodes is not None or self.angular_nodes is not None
        return "crowns" if legacy else "columns"

    @property
    def crown_nodes(self) -> tuple[int, int]:
        """Rings and angles of the per-crown quadrature."""
        return self.radial_nodes or 4, self.angular_nodes or 8

    @property
    def footprint_tolerance(self) -> float:
        """Footprint weight left out beyond the truncation radius."""
        if self.truncation_tolerance is not None:
            return self.truncation_tolerance
        if self.scheme == "crowns":
            return CROWN_SCHEME_TRUNCATION
        return min(0.1 * self.tolerance, 1e-3)

    @property
    def ground_tolerance(self) -> float:
        """Footprint weight left out beyond the truncation radius of the ground gap's
        columns: :data:`GROUND_TRUNCATION` times ``tolerance`` (at most 1e-3), or
        ``truncation_tolerance`` where given."""
        if self.truncation_tolerance is not None or self.scheme == "crowns":
            return self.footprint_tolerance
        return min(GROUND_TRUNCATION * self.tolerance, 1e-3)

    def column_spacing_for(self, footprint_sigma, crown_radius, crowns=np.inf, shapes=()) -> float:
        """Column spacing (m) at the beam centre for a footprint of σf (m) under crowns
        of typical radius ``crown_radius`` (m), of which about ``crowns`` share the
        footprint's weight (fewer than (σf/R)² average their edge errors less), with
        shape codes ``shapes`` (:data:`EDGE_SPACING_FACTOR`)."""
        if self.column_spacing is not None:
            return float(self.column_spacing)
        factor = min((EDGE_SPACING_FACTOR[SHAPE_NAMES[c]] for c in set(shapes)), default=1.0)
        spacing = self._spacing(SPACING_CONSTANT, footprint_sigma, crown_radius, crowns)
        return min(factor * spacing, max(spacing, EDGE_RESOLUTION * crown_radius))

    def ground_spacing_for(self, footprint_sigma, crown_radius, crowns=np.inf) -> float:
        """Column spacing (m) at the beam centre of the ground gap's own columns (the
        arguments of :meth:`column_spacing_for`); a given ``column_spacing`` serves
        both."""
        if self.column_spacing is not None:
            return float(self.column_spacing)
        return self._spacing(GROUND_SPACING_CONSTANT, footprint_sigma, crown_radius, crowns)

    def _spacing(self, constant, footprint_sigma, crown_radius, crowns):
        """s = constant·ε^(2/3)·R·N^(1/3), N = min((σf/R)², ``crowns``)."""
        radius = max(crown_radius, 1e-6)
        averaged = min(footprint_sigma / radius, np.sqrt(max(crowns, 1.0)))  # √N
        return constant * self.tolerance ** (2.0 / 3.0) * radius * averaged ** (2 / 3)

    def oversampling_for(self, bin_height, pulse_sigma) -> int:
        """Fine layers per digitiser bin of ``bin_height`` (m) for a pulse of σz =
        ``pulse_sigma`` (m): layers h thick with (h/σz)²/200 ≤ tolerance/8, and
        h ≤ σz/4."""
        if self.vertical_oversampling is not None:
            return int(self.vertical_oversampling)
        thickest = pulse_sigma * min(0.25, np.sqrt(25.0 * self.tolerance))
        return max(1, int(np.ceil(bin_height / max(thickest, 1e-12))))


def as_accuracy(accuracy) -> AccuracySettings:
    """Accuracy settings from None (the defaults), a tolerance (a number, or a string
    such as ``"1e-3"``), or :class:`AccuracySettings`."""
    if accuracy is None:
        return AccuracySettings()
    if isinstance(accuracy, AccuracySettings):
        return accuracy
    if isinstance(accuracy, (str, int, float, np.floating)) and not isinstance(accuracy, bool):
        try:
            value = float(accuracy)
        except ValueError:
            raise ValueError(
                f"accuracy must be a tolerance such as 1e-3 or AccuracySettings, got {accuracy!r}"
            ) from None
        return AccuracySettings(tolerance=value)
    raise TypeError(
        f"accuracy must be None, a tolerance or AccuracySettings, got {type(accuracy).__name__}"
    )
