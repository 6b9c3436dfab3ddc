"""The observation model: a simulated waveform as an instrument would record it."""

import numpy as np

from .observation import Observation


def observe(
    waveform,
    *,
    gain: float,
    baseline: float,
    noise_sigma: float,
    rng: np.random.Generator,
    shot_factor: float = 0.0,
    heights=None,
    ground_elevation: float | None = None,
    quantise: float | bool = False,
    saturation: float | None = None,
    floor_sigmas: float | None = None,
    shot_id=0,
    pulse=None,
    pulse_ns: float = np.nan,
    metadata: dict | None = None,
    noise_filter=None,
    instrument=None,
) -> Observation:
    """Turn a simulated waveform W into an observation (physics conventions)::

        y_j = b + a·W_j + ε_j,   ε_j ~ N(0, σn² + g·a·W_j)

    then optionally quantise, saturate and censor below the floor b + n·σn.

    Parameters
    ----------
    waveform : forward.Waveform or array
        Noise-free waveform W (apparent reflectance per bin). With an array, ``heights``
        gives its bin-centre heights (m above ground).
    gain : float
        a, digitiser units per unit apparent reflectance (> 0).
    baseline : float
        b, noise mean (digitiser units).
    noise_sigma : float
        σn, read-noise σ (digitiser units, ≥ 0).
    rng : numpy.random.Generator
        Source of the noise.
    shot_factor : float
        g, shot-noise variance per unit signal (digitiser units; ≥ 0).
    heights : array (m), optional
        Bin-centre heights when ``waveform`` is an array.
    ground_elevation : float (m), optional
        If given, the axis becomes elevation = height + ground_elevation.
    quantise : float or bool
        Quantisation step (True: 1 digitiser unit; False/0: none). Values are rounded.
    saturation : float, optional
        Digitiser maximum; larger values are clipped to it.
    floor_sigmas : float, optional
        If given, samples below b + floor_sigmas·σn are set to that floor and flagged as
        censored.
    shot_id, pulse, pulse_ns, metadata
        Passed to the :class:`Observation`.
    noise_filter : array, optional
        Impulse response of the digitiser's noise filter: the read noise is white noise
        convolved with it, rescaled to keep σn, so its autocorrelation is the filter's
        (R(k) = Σ h_i h_{i+k} / Σ h_i²). Default: white noise.
    instrument : str or forward.Instrument, optional
        The instrument (preset name) recorded with the observation.

    Returns
    -------
    Observation
        With the product noise fields set to the true b and σn, and ``truth`` holding
        ``ground`` (axis units), ``gain``, ``baseline``, ``noise_sigma``,
        ``shot_factor`` and ``signal`` (a·W).
    """
    if hasattr(waveform, "samples") and hasattr(waveform, "heights"):
        signal, heights = np.asarray(waveform.samples, float), np.asarray(waveform.heights)
    else:
        if heights is None:
            raise ValueError("observe: an array waveform needs its bin-centre heights")
        signal, heights = np.asarray(waveform, float), np.asarray(heights, float)
    if signal.shape != heights.shape or signal.ndim != 1:
        raise ValueError("observe: waveform and heights must be 1-D arrays of equal length")
    if not np.all(np.isfinite(signal)):
        raise ValueError("observe: the waveform has NaN or infinite samples")
    if not (gain > 0 and noise_sigma >= 0 and shot_factor >= 0):
        raise ValueError("observe: need gain > 0, noise_sigma ≥ 0 and shot_factor ≥ 0")
    if not isinstance(rng, np.random.Generator):
        raise ValueError("observe: rng must be a numpy.random.Generator")
    mean_signal = gain * np.clip(signal, 0.0, None)
    if noise_filter is None:  # white read noise and shot noise in one draw a bin
        sd = np.sqrt(noise_sigma**2 + shot_factor * mean_signal)
        y = baseline + mean_signal + sd * rng.standard_normal(signal.size)
    else:
        read_noise = noise_sigma * correlated_normal(signal.size, noise_filter, rng)
        shot_noise = np.sqrt(shot_factor * mean_signal) * rng.standard_normal(signal.size)
        y = baseline + mean_signal + read_noise + shot_noise
    step = 1.0 if quantise is True else float(quantise or 0.0)
    if step > 0:
        y = np.round(y / step) * step
    sat = np.nan
    if saturation is not None:
        sat = float(saturation)
        y = np.minimum(y, sat)
    floor, censored = np.nan, None
    if floor_sigmas is not None:
        floor = baseline + floor_sigmas * noise_sigma
        censored = y < floor
        y = np.where(censored, floor, y)
    offset = 0.0 if ground_elevation is None else float(ground_elevation)
    return Observation(
        samples=y,
        axis=heights + offset,
        axis_kind="height" if ground_elevation is None else "elevation",
        shot_id=shot_id,
        noise_mean=float(baseline),
        noise_sigma=float(noise_sigma),
        floor=floor,
        censored=censored,
        saturation=sat,
        pulse=pulse,
        pulse_ns=pulse_ns,
        instrument=getattr(instrument, "name", instrument),
        metadata=dict(metadata or {}),
        truth={
            "ground": offset,
            "gain": float(gain),
            "baseline": float(baseline),
            "noise_sigma": float(noise_sigma),
            "shot_factor": float(shot_factor),
            "signal": mean_signal,
        },
    )


def correlated_normal(size: int, impulse_response, rng: np.random.Generator) -> np.ndarray:
    """Unit-variance normal noise with the autocorrelation of a filter's impulse response."""
    kernel = np.asarray(impulse_response, float)
    if kernel.ndim != 1 or kernel.size == 0 or not np.all(np.isfinite(kernel)):
        raise ValueError("observe: the noise filter must be a finite 1-D array")
    norm = np.sqrt(np.sum(kernel**2))
    if norm == 0:
        raise ValueError("observe: the noise filter is all zeros")
    white = rng.standard_normal(size + kernel.size - 1)
    return np.convolve(white, kernel / norm, mode="valid")
