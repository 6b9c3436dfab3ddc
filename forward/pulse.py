"""Transmitted pulses, expressed in height offset d = z_sample − z_scatterer (m).

A later return comes from lower down, so a pulse's leading edge in time lies at positive
height offsets. Every pulse is normalised to unit area over d and has its peak at d = 0,
so that a flat ground returns a pulse-shaped peak centred on z = 0 (conventions, "Pulse
and digitiser"). Variants are chosen through :data:`PULSE_TYPES`.
"""

from dataclasses import dataclass, field

import numpy as np
import scipy.fft
from scipy.special import ndtr, ndtri

from .backends import jit, resolve
from .constants import FWHM_PER_SIGMA, ns_to_height


@dataclass(frozen=True)
class GaussianPulse:
    """Gaussian pulse of half-power duration ``fwhm_ns`` (ns); σz = τp·c/2/2.35482 (m).

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II and Fig. 1: the Gaussian pulse,
    and a flat ground's Gaussian-shaped return peaking at the ground's height).
    """

    fwhm_ns: float

    def __post_init__(self):
        if not np.isfinite(self.fwhm_ns) or self.fwhm_ns <= 0:
            raise ValueError(f"pulse FWHM must be positive and finite, got {self.fwhm_ns} ns")

    @property
    def sigma_m(self) -> float:
        """Standard deviation in height (m)."""
        return ns_to_height(self.fwhm_ns) / FWHM_PER_SIGMA

    def pdf(self, d):
        """Pulse density at height offsets.

        Parameters
        ----------
        d : float or array (m)
            d = z_sample − z_scatterer.

        Returns
        -------
        float or array (1/m)
            exp(−d²/2σz²)/(σz·√(2π)), of unit area.
        """
        s = self.sigma_m
        return np.exp(-0.5 * (np.asarray(d) / s) ** 2) / (s * np.sqrt(2 * np.pi))

    def cdf(self, d):
        """Pulse area below height offsets.

        Parameters
        ----------
        d : float or array (m)

        Returns
        -------
        float or array
            Φ(d/σz).
        """
        return ndtr(np.asarray(d) / self.sigma_m)

    def support(self, tolerance):
        """Offsets outside which each tail holds less than ``tolerance`` of the area.

        Parameters
        ----------
        tolerance : float

        Returns
        -------
        (float, float) (m)
            ∓σz·Φ⁻¹(tolerance).
        """
        half = -ndtri(tolerance) * self.sigma_m
        return -half, half

    def describe(self) -> dict:
        """The pulse's settings, for stored outputs.

        Returns
        -------
        dict
        """
        return {"pulse": "gaussian", "pulse_fwhm_ns": self.fwhm_ns}


@dataclass(frozen=True)
class MeasuredPulse:
    """A sampled transmit pulse (e.g. GEDI ``txwaveform``), linearly interpolated.

    Parameters
    ----------
    samples : array
        Pulse amplitude in time order, baseline already removed; negative values (noise)
        are clipped to zero.
    sample_ns : float (ns)
        Time between samples.
    """

    samples: np.ndarray
    sample_ns: float
    _offsets: np.ndarray = field(init=False, repr=False)
    _density: np.ndarray = field(init=False, repr=False)
    _cumulative: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        samples = np.asarray(self.samples, float)
        if samples.ndim != 1 or samples.size < 2:
            raise ValueError("a measured pulse needs a 1-D array of at least 2 samples")
        if not np.all(np.isfinite(samples)):
            raise ValueError("the measured pulse has NaN or infinite samples")
        if not np.isfinite(self.sample_ns) or self.sample_ns <= 0:
            raise ValueError(f"pulse sample spacing must be positive, got {self.sample_ns} ns")
        samples = np.clip(samples, 0.0, None)
        if samples.max() <= 0:
            raise ValueError("the measured pulse has no positive sample")
        peak = int(np.argmax(samples))
        # time order → height offsets: earlier samples sit above the scatterer
        offsets = -ns_to_height((np.arange(samples.size) - peak) * self.sample_ns)
        offsets, density = offsets[::-1], samples[::-1]
        steps = np.diff(offsets)
        cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (density[1:] + density[:-1]) * steps)])
        object.__setattr__(self, "_offsets", offsets)
        object.__setattr__(self, "_density", density / cumulative[-1])
        object.__setattr__(self, "_cumulative", cumulative / cumulative[-1])

    def pdf(self, d):
        """Pulse density at height offsets, linear between the samples.

        Parameters
        ----------
        d : float or array (m)

        Returns
        -------
        float or array (1/m)
            Zero outside the sampled span.
        """
        return np.interp(d, self._offsets, self._density, left=0.0, right=0.0)

    def cdf(self, d):
        """Pulse area below height offsets: the exact integral of the linear interpolant.

        Parameters
        ----------
        d : float or array (m)

        Returns
        -------
        float or array
        """
        d = np.clip(np.asarray(d, float), self._offsets[0], self._offsets[-1])
        k = np.clip(np.searchsorted(self._offsets, d, side="right") - 1, 0, self._offsets.size - 2)
        step = self._offsets[k + 1] - self._offsets[k]
        t = (d - self._offsets[k]) / step
        p0, p1 = self._density[k], self._density[k + 1]
        return self._cumulative[k] + step * (p0 * t + 0.5 * (p1 - p0) * t * t)

    def support(self, tolerance):
        """The sampled span of the pulse (finite support).

        Parameters
        ----------
        tolerance : float
            Ignored.

        Returns
        -------
        (float, float) (m)
        """
        del tolerance  # the measured pulse has finite support
        return float(self._offsets[0]), float(self._offsets[-1])

    def describe(self) -> dict:
        """The pulse's settings, for stored outputs.

        Returns
        -------
        dict
        """
        return {"pulse": "measured", "pulse_sample_ns": self.sample_ns}


PULSE_TYPES = {"gaussian": GaussianPulse, "measured": MeasuredPulse}


def support_bins(heights, centres, support):
    """First and last-plus-one bin whose height lies within a pulse's support of some
    centre.

    Parameters
    ----------
    heights : array (m)
        Ascending bin heights.
    centres : array (m)
        Heights of the point scatterers (e.g. each row's ground).
    support : (float, float) (m)
        Offsets below and above a centre beyond which the pulse is taken as zero
        (``pulse.support(tolerance)``).

    Returns
    -------
    (int, int)
    """
    low, high = support
    centres = np.asarray(centres)
    first = max(int(np.searchsorted(heights, centres.min() + low)), 0)
    last = int(np.searchsorted(heights, centres.max() + high, side="right"))
    return first, last


def point_returns(pulse, heights, centres, weights, support, *, bin_height=None, backend="auto"):
    """Samples of point scatterers: a weighted, point-sampled pulse per centre.

    Parameters
    ----------
    pulse : GaussianPulse or MeasuredPulse
    heights : array (m)
        Ascending bin heights, evenly spaced, shape (bins,).
    centres : array (m)
        Height of each scatterer, shape (n,).
    weights : array
        Return energy of each scatterer (e.g. ρg·P(0)), (n,); times the bin height
        where ``bin_height`` is left out (e.g. ρg·P(0)·Δz, m).
    support : (float, float) (m)
        Offsets beyond which the pulse is taken as zero (``pulse.support(tolerance)``).
    bin_height : float (m), optional
        Δz, the spacing of ``heights``: each weight is multiplied by it. Left out, the
        weights already hold it, and Δz is read from ``heights`` where the compiled
        kernel needs it.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` (:func:`forward.backends.resolve`):
        compiled for a Gaussian pulse only, where its samples follow from the peak by
        exact ratios (three exponentials a row), equal to the reference to rounding.

    Returns
    -------
    array, shape (n, bins)
        weights[r]·Δz·pulse(heights − centres[r]) within the support bins of the batch
        (:func:`support_bins`), zero outside.

    Notes
    -----
    A flat surface at height z_g returns w·Δz·p(z_j − z_g) in bin j (physics conventions,
    "Pulse and digitiser"): the pulse p of unit area, point-sampled at the bin centre
    z_j, times the bin height Δz. The ground of both waveform models is this pulse.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II and Fig. 1: each scatterer
    returns the pulse, registered at the pulse's peak).
    """
    centres = np.asarray(centres, float)
    out = np.zeros((centres.size, np.size(heights)))
    first, last = support_bins(heights, centres, support)
    if last <= first:
        return out
    weights = np.asarray(weights, float)
    spaced = bin_height is not None or np.size(heights) > 1  # Δz known for the kernel
    if resolve(backend) == "numba" and isinstance(pulse, GaussianPulse) and spaced:
        sigma = pulse.sigma_m
        dz = float(heights[1] - heights[0]) if bin_height is None else bin_height
        scale = 1.0 if bin_height is None else bin_height
        _gaussian_point_returns(
            out, np.ascontiguousarray(centres), np.ascontiguousarray(weights),
            float(heights[first]), float(scale / (sigma * np.sqrt(2.0 * np.pi))), float(sigma),
            float(dz / sigma), first, last,
        )  # fmt: skip
        return out
    if bin_height is not None:
        weights = weights * bin_height
    out[:, first:last] = weights[:, None] * pulse.pdf(heights[None, first:last] - centres[:, None])
    return out


@jit
def _gaussian_point_returns(out, centres, weights, h_first, scale, sigma, step, first, last):
    """The kernel of :func:`point_returns` for a Gaussian pulse of sd ``sigma`` (m), into
    ``out``: ``scale`` = Δz/(σ√(2π)) (1/(σ√(2π)) where the weights hold Δz), ``step`` =
    Δz/σ, bins ``first`` to ``last`` − 1 from ``h_first`` (m)."""
    factor = np.exp(-step * step)
    for r in range(centres.size):
        # e^{−d²/2} at d_j = d_k + (j − k)δ from the bin k nearest the centre, by its exact
        # ratios e^{±d_jδ − δ²/2} (each the previous times e^{−δ²}): three exps a row
        offset = (centres[r] - h_first) / (sigma * step)
        k = min(max(first + int(np.floor(offset + 0.5)), first), last - 1)
        d = (k - first - offset) * step
        peak = weights[r] * scale * np.exp(-0.5 * d * d)
        value, ratio = peak, np.exp(-d * step - 0.5 * step * step)
        for j in range(k, last):
            out[r, j] = value
            value *= ratio
            ratio *= factor
        value, ratio = peak, np.exp(d * step - 0.5 * step * step)
        for j in range(k - 1, first - 1, -1):
            value *= ratio
            ratio *= factor
            out[r, j] = value


def layer_kernel(pulse, bin_height, oversampling, tolerance):
    """Response of output samples to unit energy spread uniformly over one fine layer.

    Parameters
    ----------
    pulse : GaussianPulse or MeasuredPulse
    bin_height : float (m)
        Δz.
    oversampling : int
        Fine layers per bin, m; a layer is h = Δz/m thick.
    tolerance : float
        Pulse tail left out (``pulse.support(tolerance)``).

    Returns
    -------
    q_min : int
        Offset of the first kernel tap.
    taps : array
        Kernel values for offsets ``q_min, q_min + 1, …``.

    Notes
    -----
    Fine layers tile the height axis with their edges on the digitiser bin edges. For a
    bin whose centre lies ``q`` layers above the layer (``q = j·m − i`` in global indices),
    the sample is Δz/h · [C(d + h/2) − C(d − h/2)] with d = (q + (m − 1)/2)·h and C the
    pulse CDF: the exact convolution of a uniform layer with the pulse, point-sampled at
    the bin centre and multiplied by Δz.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (Sec. II-B: the returns of thin layers
    added to the digitiser bins by their delay).
    """
    m = int(oversampling)
    h = bin_height / m
    low, high = pulse.support(tolerance)
    shift = (m - 1) / 2
    q_min = int(np.floor((low - h / 2) / h - shift))
    q_max = int(np.ceil((high + h / 2) / h - shift))
    d = (np.arange(q_min, q_max + 1) + shift) * h
    taps = bin_height / h * (pulse.cdf(d + h / 2) - pulse.cdf(d - h / 2))
    return q_min, taps


def broaden(samples, bin_height: float, sigma_m, reach_m=None) -> np.ndarray:
    """Waveforms convolved with a Gaussian: the pulse widened by the receiver's response
    or by the terrain's slope and roughness within the footprint.

    Parameters
    ----------
    samples : array (n, bins)
        Waveforms on an even height axis (a sample per bin).
    bin_height : float (m)
        Δz.
    sigma_m : float or array (n,) (m)
        σ of the Gaussian, per row (0: unchanged).
    reach_m : float (m), optional
        The largest σ the zero padding must allow for, where the caller knows it (a
        prior's bound): the transform's length then depends on it alone, so that a row's
        result is the same whatever rows share its batch. The rows' largest σ if None or
        smaller.

    Returns
    -------
    array (n, bins)
        Each row convolved with N(0, σ²), by FFT over the rows padded with zeros beyond
        the window (the waveform is taken as zero outside it); each row's sum is kept
        where its return lies well inside the window.

    Notes
    -----
    The Gaussian's transfer function is exp(−ω²σ²/2), ω the angular frequency (1/m): the
    convolution of the band-limited sampled waveform is exact.
    """
    samples = np.asarray(samples, float)
    if samples.ndim != 2:
        raise ValueError("broaden needs waveforms as rows (n, bins)")
    n, bins = samples.shape
    sigma = np.broadcast_to(np.asarray(sigma_m, float), (n,))
    if np.any(~np.isfinite(sigma) | (sigma < 0)):
        raise ValueError("broadening σ must be finite and ≥ 0")
    if not np.any(sigma > 0):
        return samples.copy()
    reach = sigma.max() if reach_m is None else max(float(reach_m), sigma.max())
    pad = int(np.ceil(5.0 * reach / bin_height))
    # the shortest fast transform length, not the next power of two (half the time at
    # some window lengths)
    size = scipy.fft.next_fast_len(bins + 2 * pad, real=True)
    spectrum = scipy.fft.rfft(samples, n=size, axis=1)
    omega = 2.0 * np.pi * scipy.fft.rfftfreq(size, d=bin_height)
    spectrum *= np.exp(-0.5 * (omega[None, :] * sigma[:, None]) ** 2)
    return scipy.fft.irfft(spectrum, n=size, axis=1)[:, :bins]
