"""The observed-waveform record shared by the simulator, the readers and the inversion."""

from dataclasses import dataclass, field

import numpy as np

#: Axis kinds: heights above the ground datum, or absolute elevations.
AXIS_KINDS = ("height", "elevation")


@dataclass(eq=False)
class Observation:
    """One observed waveform in digitiser units on an ascending vertical axis.

    Parameters
    ----------
    samples : array of float
        Waveform samples (digitiser units), ordered like ``axis`` (lowest bin first; the
        readers reverse the time order of mission files).
    axis : array of float (m)
        Bin-centre heights above ground (``axis_kind="height"``) or elevations
        (``"elevation"``); strictly increasing with a uniform step.
    axis_kind : str
        ``"height"`` or ``"elevation"``.
    shot_id : int or str
        Shot identifier (shot number for mission files).
    noise_mean, noise_sigma : float
        Noise mean and standard deviation supplied with the product (digitiser units), NaN
        when unknown. Estimates made from the samples live in the analysis, not here.
    floor : float
        Value that censored samples were set to (digitiser units), NaN if none.
    censored : array of bool or None
        True where a sample was set to ``floor`` because it fell below it (the true value
        is only known to be ≤ floor).
    saturation : float
        Digitiser maximum; samples at or above it are clipped. NaN if none.
    pulse : array of float or None
        Transmit pulse samples in time order (digitiser units, baseline included).
    pulse_ns : float (ns)
        Time between transmit-pulse samples.
    instrument : str or None
        Name of the instrument preset that recorded the shot (``"gedi"``, ``"lvis"``,
        ``"slicer"``; see ``forward.INSTRUMENT_PRESETS``). The readers set it from the file;
        ``None`` when the file does not say.
    metadata : dict
        Per-shot metadata (``latitude``, ``longitude``, ``beam``, ...).
    truth : dict
        Known true values for simulated shots (``ground``, in axis units, ``gain``, ...).
    """

    samples: np.ndarray
    axis: np.ndarray
    axis_kind: str = "height"
    shot_id: object = 0
    noise_mean: float = np.nan
    noise_sigma: float = np.nan
    floor: float = np.nan
    censored: np.ndarray | None = None
    saturation: float = np.nan
    pulse: np.ndarray | None = None
    pulse_ns: float = np.nan
    instrument: str | None = None
    metadata: dict = field(default_factory=dict)
    truth: dict = field(default_factory=dict)

    def __post_init__(self):
        samples = np.asarray(self.samples, dtype=float)
        axis = np.asarray(self.axis, dtype=float)
        name = f"shot {self.shot_id}"
        if samples.ndim != 1:
            raise ValueError(f"{name}: samples must be 1-D, got shape {samples.shape}")
        if samples.size < 3:
            raise ValueError(f"{name}: empty waveform ({samples.size} samples; need ≥ 3)")
        if axis.shape != samples.shape:
            raise ValueError(
                f"{name}: ragged waveform: {samples.size} samples but {axis.size} axis values"
            )
        bad = int(np.count_nonzero(~np.isfinite(samples)))
        if bad:
            raise ValueError(f"{name}: {bad} NaN or infinite sample(s)")
        if not np.all(np.isfinite(axis)):
            raise ValueError(f"{name}: the vertical axis has NaN or infinite values")
        step = np.diff(axis)
        if np.any(step <= 0):
            raise ValueError(f"{name}: the vertical axis must be strictly increasing")
        if np.ptp(step) > 1e-6 * max(abs(step.mean()), 1e-12) + 1e-9:
            raise ValueError(f"{name}: the vertical axis is not uniformly spaced")
        if self.axis_kind not in AXIS_KINDS:
            raise ValueError(f"{name}: axis_kind must be one of {AXIS_KINDS}")
        if self.censored is not None:
            censored = np.asarray(self.censored, dtype=bool)
            if censored.shape != samples.shape:
                raise ValueError(f"{name}: censored mask shape does not match the samples")
            if censored.any() and not np.isfinite(self.floor):
                raise ValueError(f"{name}: censored samples need a finite floor value")
            self.censored = censored
        if self.pulse is not None:
            pulse = np.asarray(self.pulse, dtype=float)
            if pulse.ndim != 1 or pulse.size < 2 or not np.all(np.isfinite(pulse)):
                raise ValueError(f"{name}: transmit pulse must be a finite 1-D array")
            self.pulse = pulse
        self.samples, self.axis = samples, axis

    @property
    def n_bins(self) -> int:
        return self.samples.size

    @property
    def bin_size(self) -> float:
        """Axis step in m."""
        return float((self.axis[-1] - self.axis[0]) / (self.axis.size - 1))

    @property
    def censored_mask(self) -> np.ndarray:
        if self.censored is None:
            return np.zeros(self.samples.shape, bool)
        return self.censored

    @property
    def saturated_mask(self) -> np.ndarray:
        """True where a sample sits at the digitiser maximum."""
        if not np.isfinite(self.saturation):
            return np.zeros(self.samples.shape, bool)
        return self.samples >= self.saturation

    @property
    def valid_mask(self) -> np.ndarray:
        """Samples whose value is measured exactly (neither censored nor saturated)."""
        return ~(self.censored_mask | self.saturated_mask)

    def index_to_axis(self, index):
        """Axis value (m) at a fractional bin index."""
        return self.axis[0] + np.asarray(index, float) * self.bin_size

    def axis_to_index(self, value):
        """Fractional bin index of an axis value (m)."""
        return (np.asarray(value, float) - self.axis[0]) / self.bin_size


@dataclass(frozen=True)
class ShotError:
    """A shot that could not be turned into an :class:`Observation`, with the reason."""

    shot_id: object
    reason: str
    metadata: dict = field(default_factory=dict)
