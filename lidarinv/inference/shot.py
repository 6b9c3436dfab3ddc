"""One shot made ready for inversion, once: instrument, analysis, window and noise model.

:meth:`Shot.from_observation` takes the instrument preset with the observation's bin (and
its transmit pulse, if any), analyses the waveform (noise, signal extent, ground peak:
:func:`lidarinv.observe.analyse.analyse`), chooses the window of bins the likelihood reads
(:class:`WindowData`) and keeps the noise estimates. Everything later stages need from the
observation comes from here: the shot's nuisance priors (:meth:`Shot.nuisance_priors`),
the noise estimates held where the noise is not sampled (:meth:`Shot.noise_estimates`),
the window.
"""

from dataclasses import dataclass, replace

import numpy as np

from forward.instrument import Instrument
from lidarinv.observe.analyse import analyse
from lidarinv.observe.ground_return import fit_ground_return, registered_ground
from lidarinv.observe.instrument import pulse_sigma_bins, shot_instrument
from lidarinv.observe.observation import Observation

from .likelihood.ar_noise import integrated_time

#: The pulse broadening's prior: its sd (m) about the lower flank's fit, and its upper end.
BROADENING_PRIOR_SD_M, BROADENING_UPPER_M = 0.25, 4.0

#: The analysis's flag for a shot with two plausible grounds; its ground prior then holds both.
GROUND_AMBIGUOUS = "ground ambiguous"
#: The weight of the analysis's alternative ground in the ground prior's mixture: the
#: analysis could not tell the two apart, so the prior does not either; the data decide.
ALTERNATIVE_GROUND_WEIGHT = 0.5


@dataclass(frozen=True)
class WindowData:
    """The part of an observation that enters the likelihood.

    Attributes
    ----------
    axis : array (m)
        Bin centres on the observation's axis (ascending).
    samples : array (DN)
    censored : array of bool
        Samples at the noise floor (true value ≤ ``floor``).
    saturated : array of bool
        Samples at the digitiser maximum (true value ≥ ``saturation``).
    floor, saturation : float (DN)
    """

    axis: np.ndarray
    samples: np.ndarray
    censored: np.ndarray
    saturated: np.ndarray
    floor: float = np.nan
    saturation: float = np.nan

    @classmethod
    def from_observation(cls, obs: Observation, lo: int, hi: int) -> "WindowData":
        """Bins ``lo:hi`` of an observation.

        Parameters
        ----------
        obs : Observation
        lo, hi : int

        Returns
        -------
        WindowData

        Raises
        ------
        ValueError
            For a window of fewer than 3 bins.
        """
        if hi - lo < 3:
            raise ValueError(f"shot {obs.shot_id}: the inversion window holds {hi - lo} bins")
        part = slice(lo, hi)
        return cls(
            axis=obs.axis[part].copy(),
            samples=obs.samples[part].copy(),
            censored=obs.censored_mask[part].copy(),
            saturated=obs.saturated_mask[part].copy(),
            floor=float(obs.floor),
            saturation=float(obs.saturation),
        )

    @property
    def exact(self) -> np.ndarray:
        """Bins recorded exactly: neither censored nor saturated."""
        return ~(self.censored | self.saturated)


def pulse_quantiles(pulse, tail):
    """Height offsets below and above which a fraction ``tail`` of the pulse lies.

    Parameters
    ----------
    pulse : GaussianPulse or MeasuredPulse
    tail : float
        Fraction of the pulse's area in each tail.

    Returns
    -------
    (float, float) (m)
        The ``tail`` and 1 − ``tail`` quantiles (a measured pulse's ``support`` is its
        whole sampled span).
    """
    low, high = pulse.support(tail)
    grid = np.linspace(low, high, 4001)
    cdf = pulse.cdf(grid)
    return float(np.interp(tail, cdf, grid)), float(np.interp(1.0 - tail, cdf, grid))


@dataclass(frozen=True)
class Shot:
    """An observation made ready for inversion.

    Attributes
    ----------
    observation : Observation
    instrument : Instrument
        See :func:`lidarinv.observe.instrument.shot_instrument`.
    analysis : lidarinv.observe.analyse.ShotAnalysis
        Noise mean and σ (DN), signal extent, ground peak and its uncertainty (m).
    window : WindowData
        The bins the likelihood reads.
    pulse_range : (float, float) (m)
        Offsets below and above which 1e-3 of the pulse lies.
    ground : float (m)
        The detected ground in the model's registration (the pulse's peak on the
        ground): the lowest mode of the smoothed waveform, moved by where the broadened
        and smoothed pulse peaks (:func:`lidarinv.observe.ground_return.registered_ground`).
    broadening : float (m)
        σ of the Gaussian that widens the shot's transmitted waveform, fitted to the
        ground return's lower flank (:func:`lidarinv.observe.ground_return.
        fit_ground_return`); 0 where the shot has no transmitted waveform (a preset
        pulse is the instrument's whole response).
    has_transmitted_pulse : bool
        The shot's own transmitted waveform is its pulse (then the broadening is sampled).
    """

    observation: Observation
    instrument: Instrument
    analysis: object
    window: WindowData
    pulse_range: tuple
    ground: float = np.nan
    broadening: float = 0.0
    has_transmitted_pulse: bool = False

    @classmethod
    def from_observation(cls, obs: Observation, settings) -> "Shot":
        """Analyse an observation and choose its window.

        Parameters
        ----------
        obs : Observation
        settings : InversionSettings
            ``instrument``, ``use_measured_pulse``, ``processing`` and the window margins
            ``margin_above_m``, ``margin_below_m`` (m).

        Returns
        -------
        Shot

        Raises
        ------
        ValueError
            If the shot has no usable signal or ground peak, or its window no energy
            above the noise mean.

        Notes
        -----
        The shot is analysed exactly as ``lidarinv metrics`` analyses it
        (:func:`lidarinv.observe.analyse`, the instrument's processing defaults unless
        ``processing`` is given), so the commands agree on its status. A clipped return
        whose file gives no saturation level (a plateau at the maximum) is taken as
        saturated there: those samples enter the likelihood as censored from above. The window runs
        from ``margin_below_m`` below the lower of the signal end and the ground's pulse
        to the signal start plus the larger of ``margin_above_m`` and half the detected
        canopy height: signal-free bins above the canopy constrain the top height.
        """
        instrument = shot_instrument(
            obs, settings.instrument, measured_pulse=settings.use_measured_pulse
        )
        analysis = analyse(obs, settings.processing, instrument=instrument, metrics=False)
        if not analysis.ok:
            raise ValueError(f"shot {obs.shot_id}: {analysis.status}: {analysis.reason}")
        if "clipped" in analysis.flags:  # no saturation level in the file: the plateau's
            obs = replace(obs, saturation=float(obs.samples.max()))  # samples are ≥ it
        broadening = 0.0
        if settings.use_measured_pulse and obs.pulse is not None:
            # the transmitted waveform is not the whole response: the ground return's lower
            # flank says how much wider the effective pulse is
            noise = analysis.noise
            broadening = fit_ground_return(
                obs.samples, obs.axis, noise.mean, noise.sigma, instrument.pulse,
                analysis.ground, integrated_time(noise.autocorrelation),
            ).broadening  # fmt: skip
        smoothing_m = analysis.smoothing_bins * obs.bin_size
        ground = registered_ground(analysis.ground, instrument.pulse, broadening, smoothing_m)
        pulse_low, pulse_high = pulse_quantiles(instrument.pulse, 1e-3)
        lowest = min(ground, ground - analysis.ground + analysis.ground_alternative)
        if not (GROUND_AMBIGUOUS in analysis.flags and np.isfinite(lowest)):
            lowest = ground
        bottom = min(analysis.signal_end, lowest + pulse_low) - settings.margin_below_m
        height = analysis.signal_start - ground
        top = analysis.signal_start + max(settings.margin_above_m, 0.5 * height)
        lo = max(int(np.searchsorted(obs.axis, bottom, side="left")), 0)
        hi = min(int(np.searchsorted(obs.axis, top, side="right")), obs.n_bins)
        window = WindowData.from_observation(obs, lo, hi)
        energy = float(np.sum(np.clip(window.samples - analysis.noise_mean, 0.0, None)))
        if not energy > 0:
            raise ValueError(f"shot {obs.shot_id}: no energy above the noise mean in the window")
        measured = settings.use_measured_pulse and obs.pulse is not None
        return cls(
            obs, instrument, analysis, window, (pulse_low, pulse_high), ground, broadening,
            measured,
        )  # fmt: skip

    def alternative_ground(self) -> tuple | None:
        """The analysis's other plausible ground, in the model's registration.

        Returns
        -------
        (float, float) (m) or None
            Its elevation and sd where the analysis flags the shot "ground ambiguous",
            None otherwise. The sd is half the return's σ: a shoulder's centre is known
            no better (``lidarinv.observe.ground_candidates.candidate_uncertainty``).
        """
        a = self.analysis
        if GROUND_AMBIGUOUS not in a.flags or not np.isfinite(a.ground_alternative):
            return None
        pulse_bins = pulse_sigma_bins(self.instrument.pulse, self.observation.bin_size)
        return_sigma_m = np.hypot(pulse_bins, a.smoothing_bins) * self.observation.bin_size
        # registered as the chosen ground is: the same pulse and smoothing move both
        return self.ground - a.ground + a.ground_alternative, 0.5 * float(return_sigma_m)

    @property
    def noise_mean(self) -> float:
        """The noise mean b̂ (DN) of the analysis."""
        return float(self.analysis.noise_mean)

    @property
    def noise_sigma(self) -> float:
        """The noise σ̂ (DN) of the analysis."""
        return float(self.analysis.noise_sigma)

    def nuisance_priors(self, ground_prior_sd_m=None, top_range=(1.0, 80.0)) -> dict:
        """The shot's priors on the observation model and on the top height.

        Parameters
        ----------
        ground_prior_sd_m : float (m) or None
            Sd of the ground-elevation prior; None for the larger of one bin height and
            the ground peak fit's uncertainty.
        top_range : (float, float) (m)
            The top height's prior range before the window cuts it.

        Returns
        -------
        dict
            ``ground_elevation``: N(ĝ, sd²) truncated at ±max(6 sd, the pulse's width);
            where the analysis found two plausible grounds (:meth:`alternative_ground`),
            an even mixture of that and N(alternative, sd_alt²) (the larger of the two
            sds), truncated beyond both;
            ``gain``: log-uniform over a factor 20 either side of the window's energy
            above b̂; ``baseline``: uniform b̂ ± 5σ̂; ``noise_sigma``: log-uniform
            [σ̂/3, 3σ̂]; ``top_height``: uniform up to where the canopy leaves the window
            over the higher of the grounds.

        Raises
        ------
        ValueError
            For a non-positive ground sd, or a window without room above the ground.
        """
        from .model.priors import LogUniform, TruncatedNormal, TruncatedNormalMixture, Uniform

        a, window = self.analysis, self.window
        b, sigma = self.noise_mean, self.noise_sigma
        energy = float(np.sum(np.clip(window.samples - b, 0.0, None)))
        pulse_low, pulse_high = self.pulse_range
        g, g_sd = self.ground, ground_prior_sd_m
        if g_sd is None:
            g_sd = max(float(a.ground_uncertainty), self.observation.bin_size)
        if not (np.isfinite(g_sd) and g_sd > 0):
            raise ValueError(f"ground_prior_sd_m must be positive, got {ground_prior_sd_m}")
        g_width = max(6.0 * g_sd, pulse_high - pulse_low)
        alternative = self.alternative_ground()
        # the canopy must fit inside the window over either ground, so that empty bins
        # above it constrain it
        highest = g if alternative is None else max(g, alternative[0])
        room = window.axis[-1] - highest - pulse_high
        if room <= top_range[0] + 1.0:
            raise ValueError(
                f"shot {self.observation.shot_id}: the window leaves no room above the ground"
            )
        ground_prior = TruncatedNormal(g, g_sd, g - g_width, g + g_width)
        if alternative is not None:
            alt, alt_sd = alternative[0], max(alternative[1], g_sd)
            alt_width = max(6.0 * alt_sd, pulse_high - pulse_low)
            ground_prior = TruncatedNormalMixture(
                g, g_sd, alt, alt_sd, ALTERNATIVE_GROUND_WEIGHT,
                min(g - g_width, alt - alt_width), max(g + g_width, alt + alt_width),
            )  # fmt: skip
        return {
            "ground_elevation": ground_prior,
            "gain": LogUniform(energy / 20.0, energy * 20.0),
            "baseline": Uniform(b - 5.0 * sigma, b + 5.0 * sigma),
            "noise_sigma": LogUniform(sigma / 3.0, sigma * 3.0),
            "top_height": Uniform(top_range[0], min(top_range[1], room)),
            **self.broadening_prior(),
        }

    def broadening_prior(self) -> dict:
        """The prior of the pulse's broadening where the shot has its transmitted
        waveform: N(fit, 0.25²) truncated to [0, 4] m, the lower flank's fit give or take
        a quarter metre (the flank alone cannot tell a wider return from low vegetation
        just above the ground); none otherwise (held at 0).

        Returns
        -------
        dict
            ``{"pulse_broadening": prior}`` or ``{}``.
        """
        from .model.priors import TruncatedNormal

        if not self.has_transmitted_pulse:
            return {}
        upper = BROADENING_UPPER_M
        centre = min(self.broadening, upper)
        return {"pulse_broadening": TruncatedNormal(centre, BROADENING_PRIOR_SD_M, 0.0, upper)}

    def noise_estimates(self) -> dict:
        """The noise mean and σ held at the shot's estimates, as parameter overrides.

        Returns
        -------
        dict
            ``{"baseline": {"fixed": b̂}, "noise_sigma": {"fixed": σ̂}}``.
        """
        return {
            "baseline": {"fixed": self.noise_mean},
            "noise_sigma": {"fixed": self.noise_sigma},
        }
