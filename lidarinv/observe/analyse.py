"""One shot from samples to direct metrics, with a status instead of deep exceptions."""

from dataclasses import asdict, dataclass, field

import numpy as np

from .ground import find_ground
from .metrics import ALL_PERCENTILES, gap_profile, rh_metrics
from .noise import estimate_noise
from .observation import Observation
from .signal import signal_extent

#: Statuses a shot analysis can end with.
STATUSES = ("ok", "no signal", "no ground peak", "ground outside window")


@dataclass
class ShotAnalysis:
    """Direct metrics of one shot. Lengths in m (axis units for positions)."""

    shot_id: object
    status: str
    reason: str = ""
    flags: list = field(default_factory=list)
    noise_mean: float = np.nan
    noise_sigma: float = np.nan
    noise_source: str = ""
    floor: float = np.nan
    signal_start: float = np.nan
    signal_end: float = np.nan
    ground: float = np.nan
    ground_uncertainty: float = np.nan
    canopy_height: float = np.nan
    rh: np.ndarray | None = None
    cover: float = np.nan
    pai: float = np.nan
    metadata: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def to_dict(self) -> dict:
        """JSON-ready dictionary (NaN → None, RH as {"rh0": …})."""
        out = asdict(self)
        rh = out.pop("rh")
        if rh is not None:
            out.update({f"rh{p}": float(v) for p, v in zip(ALL_PERCENTILES, rh)})
        out["shot_id"] = json_value(self.shot_id)
        out["metadata"] = {k: json_value(v) for k, v in self.metadata.items()}
        return {k: json_value(v) for k, v in out.items()}


def json_value(value):
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def resolve_noise(obs: Observation, method: str = "auto"):
    """Noise (mean, σ, source) for a shot.

    ``"product"`` uses the values supplied with the file; ``"ends"`` and ``"histogram"``
    estimate from the samples; ``"auto"`` estimates from the ends unless most samples
    are censored (then the samples carry no noise information) and product values exist.
    """
    has_product = np.isfinite(obs.noise_mean) and np.isfinite(obs.noise_sigma)
    if method == "auto":
        censored = obs.censored_mask.mean() > 0.2
        method = "product" if censored and has_product else "ends"
    if method == "product":
        if not has_product:
            raise ValueError("the file supplies no noise mean and σ for this shot")
        return float(obs.noise_mean), float(obs.noise_sigma), "product"
    estimate = estimate_noise(obs.samples, method=method, valid=obs.valid_mask)
    if estimate.sigma <= 0:
        if has_product:
            return float(obs.noise_mean), float(obs.noise_sigma), "product"
        raise ValueError("estimated noise σ is 0 (constant or censored samples)")
    return estimate.mean, estimate.sigma, method


def analyse(
    obs: Observation,
    *,
    noise: str = "auto",
    n_sigma: float = 4.0,
    smooth_bins: float | None = 1.0,
    ground_smooth_bins: float | None = 2.0,
    rho_ratio: float = 1.5,
    extinction: float = 0.5,
) -> ShotAnalysis:
    """Noise, signal extent, ground peak, RH metrics and cover of one observation.

    A shot without signal above the floor gets status ``"no signal"``; one whose signal
    has no resolvable lowest mode gets ``"no ground peak"`` or, if the return runs into
    the bottom of the window, ``"ground outside window"``. Flags note saturation,
    censoring and returns touching the window edges (truncation).
    """
    result = ShotAnalysis(shot_id=obs.shot_id, status="ok", metadata=dict(obs.metadata))
    mean, sigma, source = resolve_noise(obs, noise)
    result.noise_mean, result.noise_sigma, result.noise_source = mean, sigma, source
    result.floor = mean + n_sigma * sigma
    if obs.saturated_mask.any():
        result.flags.append("saturated")
    if obs.censored_mask.any():
        result.flags.append("censored")
    extent = signal_extent(
        obs.samples,
        obs.axis,
        mean,
        sigma,
        n_sigma=n_sigma,
        smooth_bins=smooth_bins,
        censored=obs.censored,
    )
    if extent is None:
        result.status, result.reason = "no signal", f"nothing above mean + {n_sigma:g}σ"
        return result
    result.signal_start, result.signal_end = extent.start, extent.end
    if extent.touches_top:
        result.flags.append("truncated top")
    if extent.touches_bottom:
        result.flags.append("truncated bottom")
        result.status = "ground outside window"
        result.reason = "the return runs into the bottom of the window; the ground may lie below"
        return result
    peak = find_ground(
        obs.samples,
        obs.axis,
        mean,
        sigma,
        n_sigma=n_sigma,
        smooth_bins=ground_smooth_bins,
        valid=obs.valid_mask,
        within=(extent.end_index, extent.start_index),
    )
    if peak is None:
        result.status, result.reason = "no ground peak", "no significant mode above the floor"
        return result
    result.ground, result.ground_uncertainty = peak.position, peak.uncertainty
    result.canopy_height = extent.start - peak.position
    window = {"noise_mean": mean, "start": extent.start, "end": extent.end}
    result.rh = rh_metrics(obs.samples, obs.axis, peak.position, **window)
    profile = gap_profile(
        obs.samples,
        obs.axis,
        peak.position,
        rho_ratio=rho_ratio,
        extinction=extinction,
        **window,
    )
    result.cover, result.pai = profile.cover, profile.pai
    return result
