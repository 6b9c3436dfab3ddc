"""One shot from samples to direct metrics, with a status and flags instead of exceptions.

:func:`analyse` is the one analysis behind ``lidarinv metrics``, ``invert`` and ``batch``:
the noise, the signal extent, the ground and the status of a shot come from here, with
the defaults of the shot's instrument (:mod:`lidarinv.observe.processing`), so that the
commands never disagree about a shot.
"""

from dataclasses import dataclass, field, replace

import numpy as np

from .ground import find_ground, lower_flank_width
from .ground_candidates import candidate_uncertainty, choose_ground, ground_candidates
from .instrument import ground_return_cdf, pulse_sigma_bins, shot_instrument
from .metrics import ALL_PERCENTILES, gap_profile, rh_metrics
from .noise import (
    MIN_NOISE_BINS,
    NoiseModel,
    end_bins,
    estimate_noise,
    product_noise,
    with_smoothed_noise,
)
from .observation import Observation
from .processing import GROUND_RULES, ProcessingSettings, processing_settings
from .quality import INCONSISTENT, clipped_plateau, contradictions, sensitivity
from .signal import edge_bins, signal_extent, smooth

#: Statuses a shot analysis can end with.
STATUSES = (
    "ok",
    "no signal",
    "no ground peak",
    "ground outside window",
    "noise unknown",
    INCONSISTENT,
)
#: Flags that keep a shot with status "ok" out of the quality set (as L2A quality_flag).
QUALITY_FLAGS = (
    "saturated",
    "clipped",
    "stale return",
    "truncated top",
    "low sensitivity",
    "terrain outlier",
)
#: Passes of noise estimation and signal finding (each refines the signal-free bins).
NOISE_PASSES = 4


@dataclass
class ShotAnalysis:
    """Direct metrics of one shot. Positions in axis units (m); heights in m.

    Attributes
    ----------
    shot_id : int or str
        Shot identifier.
    status : str
        One of :data:`STATUSES`.
    reason : str
        Why a shot is not "ok".
    flags : list of str
        Notes such as "saturated", "truncated top", "low sensitivity", "stale return".
    quality : bool
        Status "ok" and none of :data:`QUALITY_FLAGS` (like GEDI L2A ``quality_flag``).
    instrument : str
        Instrument preset used.
    noise : NoiseModel or None
        The shot's noise (mean, σ, autocorrelation, smoothed σ, source).
    smoothing_bins : float
        Gaussian smoothing σ (bins) used for detection.
    start_floor, end_floor : float
        Front and back floors (digitiser units, on the smoothed waveform).
    signal_start, signal_end : float (m)
        Highest and lowest bins of the signal.
    ground, ground_uncertainty : float (m)
        Centre of the lowest mode and its 1-σ uncertainty.
    ground_width : float (m)
        Half width at half maximum of the lowest mode's lower flank on the smoothed
        waveform, as a Gaussian σ.
    n_modes : int
        Significant modes in the signal (1: a lone ground peak).
    ground_kind : str
        ``"mode"`` or ``"shoulder"`` (:mod:`lidarinv.observe.ground_candidates`).
    ground_evidence : float
        The chosen ground's evidence (σ of the windowed energy sum or chord excess, the
        weaker); ``ground_level`` is the significance level it was held to.
    ground_alternative, ground_alternative_evidence : float (m), float
        The other plausible ground and its evidence (NaN where there is none); with
        the flag "ground ambiguous" when it is a plausible return below the chosen one,
        or the lowest mode above a chosen return that is significant but not
        confidently so (:func:`lidarinv.observe.ground_candidates.choose_ground`).
    canopy_height : float (m)
        Signal start above the ground (RH100).
    rh : array (m) or None
        RH0 … RH100 above the ground.
    cover, pai : float
        Direct gap-probability cover and plant area index (m² m⁻²).
    pavd : array (m² m⁻³) or None
        Plant area volume density of layers ``pavd_layer_m`` thick from the ground up.
    pavd_layer_m : float (m)
        Thickness of the PAVD layers.
    sensitivity : float
        Largest canopy cover under which this shot would still detect the ground.
    latitude, longitude : float (degrees)
        Position of the ground return where the file geolocates the window.
    terrain_expected, terrain_residual, terrain_allowance : float (m)
        The ground its track neighbours predict, the departure from it and the largest
        departure the terrain allows (:mod:`lidarinv.observe.terrain`; NaN unless a
        file's shots were checked together).
    metadata : dict
        The reader's per-shot metadata.
    """

    shot_id: object
    status: str
    reason: str = ""
    flags: list = field(default_factory=list)
    quality: bool = False
    instrument: str = ""
    noise: NoiseModel | None = None
    smoothing_bins: float = np.nan
    start_floor: float = np.nan
    end_floor: float = np.nan
    signal_start: float = np.nan
    signal_end: float = np.nan
    ground: float = np.nan
    ground_uncertainty: float = np.nan
    ground_width: float = np.nan
    n_modes: int = 0
    ground_kind: str = ""
    ground_evidence: float = np.nan
    ground_level: float = np.nan
    ground_alternative: float = np.nan
    ground_alternative_evidence: float = np.nan
    canopy_height: float = np.nan
    rh: np.ndarray | None = None
    cover: float = np.nan
    pai: float = np.nan
    pavd: np.ndarray | None = None
    pavd_layer_m: float = np.nan
    sensitivity: float = np.nan
    latitude: float = np.nan
    longitude: float = np.nan
    terrain_expected: float = np.nan
    terrain_residual: float = np.nan
    terrain_allowance: float = np.nan
    metadata: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def noise_mean(self) -> float:
        return np.nan if self.noise is None else self.noise.mean

    @property
    def noise_sigma(self) -> float:
        return np.nan if self.noise is None else self.noise.sigma

    @property
    def noise_source(self) -> str:
        return "" if self.noise is None else self.noise.source

    def to_dict(self) -> dict:
        """A flat, JSON-ready record (NaN → None; RH as rh0…rh100, PAVD as pavd_0_5…)."""
        out = {
            "shot_id": self.shot_id,
            "status": self.status,
            "reason": self.reason,
            "flags": list(self.flags),
            "quality": self.quality,
            "instrument": self.instrument,
            "latitude": self.latitude,
            "longitude": self.longitude,
            "ground": self.ground,
            "ground_uncertainty": self.ground_uncertainty,
            "ground_kind": self.ground_kind,
            "ground_evidence": self.ground_evidence,
            "ground_level": self.ground_level,
            "ground_alternative": self.ground_alternative,
            "ground_alternative_evidence": self.ground_alternative_evidence,
            "signal_start": self.signal_start,
            "signal_end": self.signal_end,
            "canopy_height": self.canopy_height,
            "terrain_expected": self.terrain_expected,
            "terrain_residual": self.terrain_residual,
            "terrain_allowance": self.terrain_allowance,
            "n_modes": self.n_modes,
            "cover": self.cover,
            "pai": self.pai,
            "sensitivity": self.sensitivity,
            "smoothing_bins": self.smoothing_bins,
            "start_floor": self.start_floor,
            "end_floor": self.end_floor,
        }
        if self.noise is not None:
            out.update(self.noise.describe())
        if self.rh is not None:
            out.update({f"rh{p}": float(v) for p, v in zip(ALL_PERCENTILES, self.rh)})
        if self.pavd is not None:
            step = self.pavd_layer_m
            for i, value in enumerate(self.pavd):
                out[f"pavd_{i * step:g}_{(i + 1) * step:g}"] = float(value)
        out["metadata"] = {k: json_value(v) for k, v in self.metadata.items()}
        return {k: json_value(v) for k, v in out.items()}


def json_value(value):
    """A numpy scalar as a plain value; non-finite floats as ``None``."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def _geolocate(result: ShotAnalysis, obs: Observation) -> None:
    """Latitude and longitude of the ground (or of the window) from the reader's metadata."""
    meta = obs.metadata
    keys = ("latitude_top", "longitude_top", "latitude_bottom", "longitude_bottom")
    if all(np.isfinite(meta.get(k, np.nan)) for k in keys) and np.isfinite(result.ground):
        t = (obs.axis[-1] - result.ground) / (obs.axis[-1] - obs.axis[0])
        for name in ("latitude", "longitude"):
            top, bottom = meta[f"{name}_top"], meta[f"{name}_bottom"]
            setattr(result, name, float(top + t * (bottom - top)))
        return
    result.latitude = float(meta.get("latitude", np.nan))
    result.longitude = float(meta.get("longitude", np.nan))


def _noise(obs, settings, smoothed, smoothing, free, edge):
    """Noise from the signal-free bins, or the file's values where asked or where the
    samples hold too few signal-free bins."""
    has_product = np.isfinite(obs.noise_mean) and np.isfinite(obs.noise_sigma)
    if settings.noise == "samples":
        interior = free.copy()
        if edge:
            interior[:edge] = interior[-edge:] = False
        if interior.sum() >= MIN_NOISE_BINS:
            noise = estimate_noise(obs.samples, free, max_lag=settings.noise_max_lag)
            noise = with_smoothed_noise(noise, smoothed, interior, smoothing)
            if noise.sigma > 0:
                return replace(
                    noise, product_mean=float(obs.noise_mean), product_sigma=float(obs.noise_sigma)
                )
    if has_product:
        return product_noise(obs.noise_mean, obs.noise_sigma, smoothing)
    raise ValueError("too few signal-free bins to measure the noise and no noise in the file")


def analyse(
    obs: Observation,
    settings: ProcessingSettings | None = None,
    *,
    instrument=None,
    metrics: bool = True,
) -> ShotAnalysis:
    """Noise, signal extent, ground, RH metrics, cover and quality of one shot.

    Parameters
    ----------
    obs : Observation
        The shot.
    settings : ProcessingSettings, optional
        Default: the processing defaults of the shot's instrument.
    instrument : str or forward.Instrument, optional
        Overrides the instrument the file names (needed when it names none).
    metrics : bool
        Compute RH, cover, PAVD and sensitivity; the inversion, which needs only the
        noise, the signal extent and the ground, turns them off (the status is the same).

    Returns
    -------
    ShotAnalysis
        Status "ok" with the metrics, or another status with its reason; never raises
        for a shot's content (only for an unknown instrument).

    Examples
    --------
    A synthetic GEDI shot (the expected waveform of a stand with its tallest trees at
    22 m over ground at 0 m, with read noise):

    >>> import numpy as np
    >>> from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot
    >>> from lidarinv.observe import analyse
    >>> shot = synthetic_shot(
    ...     SYNTHETIC_SHOTS["gedi-mixed"], np.random.default_rng(1), explicit=False
    ... )
    >>> analysis = analyse(shot)
    >>> analysis.status, analysis.instrument
    ('ok', 'gedi')
    >>> bool(abs(analysis.ground) < 0.5)
    True
    >>> bool(15.0 < analysis.rh[98] < 22.0)
    True
    """
    if instrument is None or isinstance(instrument, str):
        instrument = shot_instrument(obs, instrument)
    settings = processing_settings(instrument.name) if settings is None else settings
    result = ShotAnalysis(
        shot_id=obs.shot_id, status="ok", instrument=instrument.name, metadata=dict(obs.metadata)
    )
    pulse_bins = pulse_sigma_bins(instrument.pulse, obs.bin_size)
    smoothing = settings.smoothing_bins
    if smoothing is None:
        smoothing = settings.smoothing_pulse_widths * pulse_bins
    result.smoothing_bins = float(smoothing)
    _flag_samples(result, obs)
    smoothed = smooth(obs.samples, smoothing)
    edge = edge_bins(smoothing)
    guard = int(np.ceil(settings.noise_guard_pulse_widths * pulse_bins))
    valid = obs.valid_mask
    try:
        free = end_bins(obs.n_bins) & valid
    except ValueError as error:
        return _stop(result, "noise unknown", str(error))
    extent = None
    for _ in range(NOISE_PASSES):
        try:
            noise = _noise(obs, settings, smoothed, smoothing, free, edge)
        except ValueError as error:
            if extent is None:
                return _stop(result, "noise unknown", str(error))
            break  # keep the previous pass's noise and extent
        start_floor = noise.detection_floor(settings.start_sigmas, settings.floor_units)
        end_floor = noise.detection_floor(settings.end_sigmas, settings.floor_units)
        extent = signal_extent(
            smoothed,
            obs.axis,
            start_floor,
            end_floor,
            min_run=settings.min_run,
            edge=edge,
            edge_floor=noise.mean + np.sqrt(2.0) * (start_floor - noise.mean),
            censored=obs.censored,
        )
        result.noise, result.start_floor, result.end_floor = noise, start_floor, end_floor
        if extent is None or noise.source == "product":
            break
        outside = ~_faint_signal(smoothed, noise, settings.noise_mask_sigmas, guard) & valid
        outside[max(extent.end_index - guard, 0) : extent.start_index + guard + 1] = False
        if np.array_equal(outside, free):
            break
        free = outside
    if result.noise.source == "product":
        result.flags.append("noise from product")
    if extent is None:
        floor = f"mean + {settings.start_sigmas:g}σ of the {settings.floor_units} noise"
        return _stop(result, "no signal", f"nothing above {floor}")
    result.signal_start, result.signal_end = extent.start, extent.end
    if extent.touches_top:
        result.flags.append("truncated top")
    if extent.touches_bottom:
        result.flags.append("truncated bottom")
        return _stop(
            result,
            "ground outside window",
            "the return runs into the bottom of the window; the ground may lie below",
        )
    peak = find_ground(
        smoothed,
        obs.axis,
        result.noise,
        floor=result.end_floor,
        prominence_sigmas=settings.prominence_sigmas,
        within=(extent.end_index, extent.start_index),
    )
    if peak is None:
        return _stop(result, "no ground peak", "no significant mode above the back floor")
    result.ground, result.ground_uncertainty = peak.position, peak.uncertainty
    result.ground_width = peak.width
    result.n_modes = peak.n_modes
    rule = GROUND_RULES[settings.ground_rule]
    lowest = max(edge, 1) if rule["below_back_floor"] else extent.end_index
    _weak_ground(result, obs, smoothed, free, int(np.rint(peak.index)), lowest, pulse_bins, rule)
    result.canopy_height = extent.start - result.ground
    _geolocate(result, obs)
    if metrics:
        _metrics(result, obs, smoothed, settings, instrument, np.hypot(pulse_bins, smoothing))
        if result.sensitivity < settings.min_sensitivity:
            result.flags.append("low sensitivity")
        failed = _contradictions(result, obs, smoothed, instrument, np.hypot(pulse_bins, smoothing))
        if failed:
            result.flags.extend(failed)
            return _stop(result, INCONSISTENT, "; ".join(failed))
    result.quality = not any(flag in QUALITY_FLAGS for flag in result.flags)
    return result


def _weak_ground(result, obs, smoothed, free, lowest_mode, lowest_bin, pulse_bins, rule) -> None:
    """Replace the lowest mode by a weaker, lower return where the noise says it is one
    (:mod:`lidarinv.observe.ground_candidates`), and report the alternative."""
    return_bins = float(np.hypot(pulse_bins, result.smoothing_bins))
    candidates, level, plausible_level = ground_candidates(
        obs.samples,
        smoothed,
        obs.axis,
        result.noise,
        lowest_mode=lowest_mode,
        lowest_bin=lowest_bin,
        return_sigma_bins=return_bins,
        signal_free=free if result.noise.source == "samples" else None,
    )
    choice = choose_ground(candidates, level, plausible_level, kinds=rule["kinds"])
    chosen = choice.chosen
    result.ground_kind, result.ground_level = chosen.kind, level
    result.ground_evidence = chosen.evidence()
    if choice.alternative is not None:
        result.ground_alternative = choice.alternative.position
        result.ground_alternative_evidence = choice.alternative.evidence()
    if choice.ambiguous:
        result.flags.append("ground ambiguous")
    if chosen is candidates[-1]:
        return
    result.ground = chosen.position
    result.ground_uncertainty = candidate_uncertainty(chosen, return_bins * obs.bin_size)
    # a ground below the back floor: the signal ends below its return, two widths down
    result.signal_end = min(result.signal_end, chosen.position - 2.0 * return_bins * obs.bin_size)
    result.signal_end = max(result.signal_end, float(obs.axis[0]))
    centred = np.asarray(smoothed, float) - result.noise.mean
    result.ground_width = lower_flank_width(centred, int(np.rint(chosen.index))) * obs.bin_size
    result.n_modes += 1


def _contradictions(result, obs, smoothed, instrument, return_width_bins) -> list:
    """Checks of the metrics against each other (:func:`quality.contradictions`) on the
    smoothed energy above the noise inside the signal extent."""
    axis = obs.axis
    inside = (axis >= result.signal_end) & (axis <= result.signal_start)
    energy = np.clip(np.asarray(smoothed, float) - result.noise.mean, 0.0, None) * inside
    return contradictions(
        energy_below_ground=float(energy[axis < result.ground].sum()),
        total_energy=float(energy.sum()),
        rh=result.rh,
        cover=result.cover,
        return_fwhm_m=2.0 * np.sqrt(2.0 * np.log(2.0)) * return_width_bins * obs.bin_size,
        ground_cdf=ground_return_cdf(instrument.pulse, result.smoothing_bins * obs.bin_size),
    )


def _faint_signal(smoothed, noise, n_sigmas, guard) -> np.ndarray:
    """Bins within ``guard`` of a smoothed value above ``mean + n_sigmas·σ`` of the
    smoothed noise: returns too faint to count as signal (a weak canopy top) but bright
    enough to bias the noise if left among the signal-free bins."""
    above = (np.asarray(smoothed) - noise.mean > n_sigmas * noise.smoothed_sigma).astype(float)
    return np.convolve(above, np.ones(2 * guard + 1), mode="same") > 0


def _flag_samples(result, obs) -> None:
    if obs.saturated_mask.any():
        result.flags.append("saturated")
    elif clipped_plateau(obs.samples):
        result.flags.append("clipped")
    if obs.censored_mask.any():
        result.flags.append("censored")
    if obs.metadata.get("stale_return"):
        result.flags.append("stale return")


def _stop(result: ShotAnalysis, status: str, reason: str) -> ShotAnalysis:
    result.status, result.reason, result.quality = status, reason, False
    return result


def _metrics(result, obs, smoothed, settings, instrument, return_width_bins) -> None:
    """RH, cover, PAI, PAVD and sensitivity of a shot whose ground was found."""
    energy = smoothed if settings.rh_smoothed else obs.samples
    window = {"start": result.signal_start, "end": result.signal_end}
    baseline = result.noise.mean if settings.rh_energy == "above-noise" else 0.0
    result.rh = rh_metrics(energy, obs.axis, result.ground, noise_mean=baseline, **window)
    smoothing_m = result.smoothing_bins * obs.bin_size if settings.rh_smoothed else 0.0
    # cover takes the whole return: the extent widened by three widths of a return
    margin = 3.0 * return_width_bins * obs.bin_size
    profile = gap_profile(
        energy,
        obs.axis,
        result.ground,
        noise_mean=result.noise.mean,
        start=min(result.signal_start + margin, obs.axis[-1]),
        end=max(result.signal_end - margin, obs.axis[0]),
        rho_ratio=settings.rho_ratio,
        extinction=instrument.extinction_per_favd,
        ground_cdf=ground_return_cdf(instrument.pulse, smoothing_m),
    )
    result.cover, result.pai = profile.cover, profile.pai
    result.pavd = profile.layer_pavd(settings.pavd_layer_m)
    result.pavd_layer_m = settings.pavd_layer_m
    # the weakest detectable ground: a return of the smoothed pulse's width at the back floor
    smallest_ground = (
        (result.end_floor - result.noise.mean) * np.sqrt(2 * np.pi) * return_width_bins
    )
    total = profile.canopy_energy + profile.ground_energy
    result.sensitivity = sensitivity(smallest_ground, total, settings.rho_ratio)
