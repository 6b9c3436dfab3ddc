"""Numerical settings and output of the expected-waveform model
(:class:`forward.expected.ExpectedWaveformModel`)."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ModelSettings:
    """Numerical settings of the expected model.

    Parameters
    ----------
    radial_nodes : int
        Gauss–Legendre nodes in ρ² across the crown disc.
    height_nodes : int
        Grid points of the height tables.
    tail : float
        Height-distribution probability left out in each tail of the grid.
    oversampling : int or None
        Fine layers per bin; ``None`` uses the explicit engine's rule (layers ≤ σz/4).
    depth_nodes : int or None
        ``None``: evaluate the tree optical depth at every fine-layer edge. An integer:
        evaluate E[P] on about that many heights from 0 to the template's tallest tree
        (a step of whole fine layers) and interpolate to the edges by Catmull–Rom: much
        cheaper, and smooth because the depth is already averaged over the heights. Rows
        whose heights are too nearly equal for that (:data:`GRID_BLEND_SD_CELLS`) take
        exact depths.
    max_elements : int
        Rows are processed in chunks so that no work array exceeds this many elements.
    backend : str
        ``"numba"`` (compiled depth, assembly and ground; needs numba), ``"numpy"``, or
        ``"auto"``: numba when it can be imported (:func:`forward.backends.resolve`).
        Both give the same results to rounding.
    """

    radial_nodes: int = 6
    height_nodes: int = 24
    tail: float = 1e-6
    oversampling: int | None = None
    depth_nodes: int | None = 32
    max_elements: int = 4_000_000
    backend: str = "auto"


#: Largest undershoot below zero accepted from the fast grid path, relative to the row's
#: canopy energy; rows beyond it are recomputed on the per-edge path.
GRID_UNDERSHOOT = 1e-5

#: Narrowest height distributions (sd, in grid cells) the grid path blends with the per-edge
#: path: below the first every row takes the per-edge path, above the second the grid alone,
#: and between them a smooth blend, so that the waveform stays continuous in the height sd.
#: Trees of nearly one height put kinks in E[P] at their crowns' tops and bases that a
#: Catmull–Rom grid of cells five bins thick misses: measured on a two-storey LVIS stand,
#: the grid's error was 2.3 % of the peak at an sd of 0.1 m, 0.75 % at 0.2 m, 0.08 % at one
#: cell (0.8 m) and 0.014 % at two (issue 46).
GRID_BLEND_SD_CELLS = (1.0, 2.0)

#: Cells of the grid path beyond the tallest canopy of a batch (E[P] = 1 there): the
#: interpolation's four-point stencil then never meets the grid's end within any row's
#: canopy, so that a row's samples do not depend on the other rows of its batch.
GRID_MARGIN_CELLS = 2

#: Revision of the model's numerics: a posterior stored with another (the long reference
#: runs of ``studies/reference_posteriors.py``) is that of a slightly different model.
#: 2: the grid path continuous in the ground elevation, exact depths for cohorts of
#: nearly one height (issue 46).
NUMERICS_REVISION = 2

#: Settings taken as converged (the reference of the benchmark and the convergence test).
CONVERGED = ModelSettings(radial_nodes=48, height_nodes=1024, tail=1e-9, depth_nodes=None)


@dataclass(frozen=True)
class ExpectedWaveforms:
    """Output of :meth:`forward.expected.ExpectedWaveformModel.evaluate` (arrays of
    shape (n, n_bins)).

    ``samples = canopy + ground``; rows with ``valid`` False hold zeros.
    ``gap_ground`` (n,) is E[P(0)].
    """

    samples: np.ndarray
    canopy: np.ndarray
    ground: np.ndarray
    gap_ground: np.ndarray
    valid: np.ndarray


def engine_oversampling(instrument):
    """Fine layers per bin by the explicit engine's default rule.

    Parameters
    ----------
    instrument : Instrument

    Returns
    -------
    int
        The least m with a layer Δz/m no thicker than σz/4 of the pulse (its ±1σ range
        over 8).
    """
    low, high = instrument.pulse.support(0.1587)
    return max(1, int(np.ceil(8.0 * instrument.bin_height / max(high - low, 1e-12))))
