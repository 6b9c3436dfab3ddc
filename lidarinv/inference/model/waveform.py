"""The model stage for one shot: parameters → stand → expected waveform.

:class:`ShotModel` maps parameter rows to the expected model's vectors
(:class:`.stand.StandMapping`, by field name) and evaluates the expected waveforms on the
shot's window (:class:`forward.expected.ExpectedWaveformModel`): the signal W of each
row, its validity, and the derived quantities, including the relative heights of the
model waveform (:func:`relative_heights`).
"""

from typing import NamedTuple

import numpy as np

from forward.backends import jit
from forward.pulse import broaden

from .stand import StandMapping

#: RH levels reported per posterior sample, by name.
RH_LEVELS = {"rh50": 0.5, "rh98": 0.98}

#: Quantities of the model waveform reported per posterior sample: name → units. The RH
#: levels, and the tree canopy's gap-probability cover, the quantity GEDI L2B's
#: ``cover`` estimates: 1 − E[P(0)]/P_u, the footprint-weighted gap through the tree
#: crowns down to the top of the understory (P_u = exp(−k·G·Ω·LAI_u), the uniform
#: understory's own gap; a return from within a pulse width of the ground, as the
#: understory's is, counts as ground in a gap-probability retrieval).
WAVEFORM_QUANTITIES = {**dict.fromkeys(RH_LEVELS, "m"), "gap_cover": "1"}

_LEVELS = np.array(list(RH_LEVELS.values()))


class ModelRows(NamedTuple):
    """The model stage's output for a batch of parameter rows.

    Attributes
    ----------
    signal : array (n, bins)
        Expected waveforms W (apparent reflectance per bin, ρg = 1); zeros where not
        ``valid``.
    valid : array of bool (n,)
        Rows the expected model takes as physical stands.
    derived : dict
        Per-row derived quantities (:meth:`.stand.StandMapping.model_vectors`, and
        :data:`WAVEFORM_QUANTITIES`: the RH of :data:`RH_LEVELS`, m above the row's
        ground, and the gap cover).
    """

    signal: np.ndarray
    valid: np.ndarray
    derived: dict


class ShotModel:
    """Parameters → stand → expected waveform on one shot's window.

    Parameters
    ----------
    mapping : StandMapping
    expected : forward.expected.ExpectedWaveformModel
        Built on the window's axis with ``free=mapping.model_free``.
    broadening_reach_m : float (m), optional
        The largest ``pulse_broadening`` a row may have (its prior's upper bound): the
        broadening's padding is sized for it, not for the batch's widest row
        (:func:`forward.pulse.broaden`), so that a row's waveform does not depend on the
        rows beside it.
    """

    def __init__(self, mapping: StandMapping, expected, broadening_reach_m=None):
        if tuple(expected.parameter_names) != tuple(mapping.model_free):
            raise ValueError("the expected model must be built with free=mapping.model_free")
        self.mapping, self.expected = mapping, expected
        self.broadening_reach_m = broadening_reach_m

    @property
    def axis(self) -> np.ndarray:
        """The window's bin centres (m)."""
        return self.expected.heights

    def valid(self, values) -> np.ndarray:
        """Rows whose parameters describe a stand (:meth:`.stand.StandMapping.valid`).

        Parameters
        ----------
        values : dict

        Returns
        -------
        array of bool (n,)
        """
        return self.mapping.valid(values)

    def widen(self, samples, values) -> np.ndarray:
        """Waveforms widened by each row's ``pulse_broadening`` (m), where it is not zero
        (:func:`forward.pulse.broaden`): the transmitted pulse made the shot's effective
        pulse.

        Parameters
        ----------
        samples : array (n, bins)
        values : dict

        Returns
        -------
        array (n, bins)
        """
        width = values.get("pulse_broadening")
        if width is None or not np.any(np.asarray(width) > 0):
            return samples
        bin_height = self.expected.instrument.bin_height
        return broaden(samples, bin_height, width, self.broadening_reach_m)

    def evaluate(self, values) -> ModelRows:
        """Expected waveforms and derived quantities of parameter rows, the waveforms
        widened by :meth:`widen`.

        Parameters
        ----------
        values : dict
            Every parameter's (n,) values; rows must be :meth:`valid`.

        Returns
        -------
        ModelRows
        """
        vectors, derived = self.mapping.model_vectors(values)
        result = self.expected.evaluate(vectors)
        samples = self.widen(result.samples, values)
        heights = relative_heights(samples, self.axis, values["ground_elevation"], _LEVELS)
        for i, name in enumerate(RH_LEVELS):
            derived[name] = heights[:, i]
        understory_gap = np.exp(
            -self.expected.instrument.extinction_per_favd * values.get("understory_lai", 0.0)
        )
        derived["gap_cover"] = 1.0 - result.gap_ground / understory_gap
        return ModelRows(samples, result.valid, derived)


@jit
def _relative_heights(signal, start, dz, ground, levels):
    """The kernel of :func:`relative_heights` (``start``: the first bin's lower edge)."""
    n, bins = signal.shape
    out = np.full((n, levels.size), np.nan)
    cum = np.empty(bins)
    for r in range(n):
        acc = 0.0
        for j in range(bins):
            acc += max(signal[r, j], 0.0)
            cum[j] = acc
        if not acc > 0.0:
            continue
        for i in range(levels.size):
            target = levels[i] * acc
            k = 0
            while k < bins - 1 and cum[k] < target:
                k += 1
            below = cum[k - 1] if k > 0 else 0.0
            step = cum[k] - below
            frac = (target - below) / step if step > 0.0 else 0.0
            frac = min(max(frac, 0.0), 1.0)
            out[r, i] = start + (k + frac) * dz - ground[r]
    return out


def relative_heights(signal, axis, ground, levels=(0.5, 0.98)) -> np.ndarray:
    """Relative heights of model waveforms, compiled.

    Parameters
    ----------
    signal : array (n, bins)
        Waveforms on ``axis``.
    axis : array (bins,) (m)
        Bin centres, ascending in equal steps.
    ground : array (n,) (m)
        Each row's ground elevation on the axis.
    levels : sequence of float
        Energy fractions in [0, 1].

    Returns
    -------
    array (n, len(levels)) (m)
        Heights above ``ground`` below which each fraction of the energy lies; NaN for
        rows without energy.

    Notes
    -----
    Each bin's energy max(W_j, 0) is spread uniformly over the bin, so the cumulative
    energy is piecewise linear between bin edges: the GEDI L2A convention of
    :func:`lidarinv.observe.metrics.rh_metrics`, the RH of record, which the tests hold
    this kernel to.
    """
    dz = float(axis[1] - axis[0])
    return _relative_heights(
        np.ascontiguousarray(signal, dtype=np.float64),
        float(axis[0]) - 0.5 * dz,
        dz,
        np.ascontiguousarray(ground, dtype=np.float64),
        np.asarray(levels, dtype=np.float64),
    )
