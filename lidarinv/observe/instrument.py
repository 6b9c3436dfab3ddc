"""The instrument of a shot: the preset named by its file, its bin and its own pulse."""

import numpy as np
from scipy.signal import fftconvolve

from forward.constants import FWHM_PER_SIGMA, SPEED_OF_LIGHT_M_PER_NS
from forward.instrument import INSTRUMENT_PRESETS, Instrument, instrument_preset
from forward.pulse import MeasuredPulse

from .observation import Observation

#: Transmit-pulse samples this many baseline σ above the baseline belong to the pulse.
PULSE_SIGNAL_SIGMAS = 3.0


def transmit_pulse(samples, sample_ns: float) -> MeasuredPulse:
    """A shot's transmitted waveform as a unit-area pulse.

    The baseline and its σ come from the first tenth of the record (before the pulse;
    at least 4 samples); the pulse is the contiguous run of samples around the maximum
    that stay above baseline + 3σ, widened by one sample on each side. Baseline noise
    outside that run is set to zero, so that it does not widen the pulse's support.

    Parameters
    ----------
    samples : array of float
        Transmit waveform in time order (digitiser units, baseline included).
    sample_ns : float (ns)
        Time between samples.
    """
    samples = np.asarray(samples, float)
    if samples.ndim != 1 or samples.size < 8 or not np.all(np.isfinite(samples)):
        raise ValueError("a transmit pulse needs a finite 1-D record of at least 8 samples")
    lead = samples[: max(4, samples.size // 10)]
    baseline = float(np.median(lead))
    spread = float(np.std(lead))
    above = samples - baseline > max(PULSE_SIGNAL_SIGMAS * spread, 1e-9)
    peak = int(np.argmax(samples))
    if not above[peak]:
        raise ValueError("the transmit pulse does not rise above its baseline")
    # the run of samples above the floor around the peak, and one sample either side
    before = np.flatnonzero(~above[:peak])
    after = np.flatnonzero(~above[peak:])
    first = int(before[-1]) if before.size else 0
    stop = peak + int(after[0]) + 1 if after.size else samples.size
    pulse = np.zeros_like(samples)
    pulse[first:stop] = samples[first:stop] - baseline
    return MeasuredPulse(pulse, float(sample_ns))


def pulse_fwhm_m(pulse) -> float:
    """Full width at half maximum of a pulse (m of height), from its density."""
    low, high = pulse.support(1e-6)
    grid = np.linspace(low, high, 4001)
    density = pulse.pdf(grid)
    above = grid[density >= 0.5 * density.max()]
    return float(above[-1] - above[0]) if above.size > 1 else float(grid[1] - grid[0])


def ground_return_cdf(pulse, smoothing_m: float = 0.0):
    """Cumulative fraction of a flat ground's return below each height offset from the
    return's peak, for the pulse as the analysis sees it (smoothed by a Gaussian of σ
    ``smoothing_m`` m). A symmetric pulse gives ½ at the peak; a pulse with a tail in
    time (GEDI, LVIS) puts more of its energy below its peak.

    Returns
    -------
    callable
        ``cdf(d)`` for height offsets ``d`` (m) from the peak.
    """
    low, high = pulse.support(1e-6)
    pad = 5.0 * smoothing_m
    step = min((high - low) / 2000.0, 0.01)
    grid = np.arange(low - pad, high + pad + step, step)
    density = pulse.pdf(grid)
    if smoothing_m > 0:
        offsets = np.arange(-pad, pad + step / 2, step)
        kernel = np.exp(-0.5 * (offsets / smoothing_m) ** 2)
        # by FFT: the direct sum costs (grid × kernel) and ran ~1 ms a call
        density = fftconvolve(density, kernel / kernel.sum(), mode="same")
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (density[1:] + density[:-1]))])
    cumulative /= cumulative[-1]
    centred = grid - grid[int(np.argmax(density))]
    return lambda d: np.interp(d, centred, cumulative)


def pulse_sigma_bins(pulse, bin_size: float) -> float:
    """The pulse's FWHM as a Gaussian σ, in bins of ``bin_size`` m."""
    return pulse_fwhm_m(pulse) / FWHM_PER_SIGMA / bin_size


def shot_instrument(
    obs: Observation, name: str | None = None, *, measured_pulse: bool = True
) -> Instrument:
    """The instrument that recorded a shot.

    Parameters
    ----------
    obs : Observation
        The shot; its ``instrument`` names the preset unless ``name`` overrides it.
    name : str, optional
        Instrument preset to use instead of the file's.
    measured_pulse : bool
        Use the shot's transmitted waveform as its pulse where the file has one.

    Returns
    -------
    forward.Instrument
        The preset with the shot's bin duration and, if any, its own pulse.
    """
    chosen = name or obs.instrument
    if chosen is None:
        raise ValueError(
            f"shot {obs.shot_id}: the file does not say which instrument recorded it; "
            f"name one ({', '.join(INSTRUMENT_PRESETS)})"
        )
    bin_ns = 2.0 * obs.bin_size / SPEED_OF_LIGHT_M_PER_NS
    instrument = instrument_preset(chosen, bin_ns=bin_ns)
    if measured_pulse and obs.pulse is not None and np.isfinite(obs.pulse_ns):
        instrument = instrument.with_overrides(pulse=transmit_pulse(obs.pulse, obs.pulse_ns))
    return instrument
