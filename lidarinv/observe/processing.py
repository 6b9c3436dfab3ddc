"""Per-instrument defaults of the shot analysis (smoothing, floors, RH convention, cover).

The defaults follow the instruments' own processing (GEDI L2A ATBD, Hofton & Blair 2019,
whose algorithm was adapted from LVIS's; LVIS L2, Blair, Rabine & Hofton 1999): the
waveform is smoothed by a Gaussian as wide as the transmitted pulse (GEDI L2A's default
setting group smooths by 6.5 ns, about the σ of GEDI's 15–16 ns pulse; here the σ of each
shot's own pulse); the signal start is the highest bin of the smoothed waveform above a
*front* floor, the signal end the lowest above a *back* floor twice as high (the GEDI
default setting group puts its floors at 3 and 6 times its noise σ), and the ground is
the lowest significant mode. The back floor is the higher because the trailing edge
below the ground carries detector tails and slow baseline wander.

Where GEDI counts its floors in the σ of its L1B noise estimate, lidarinv counts them in
the σ of the *smoothed* noise, measured on each shot's signal-free bins, so that a floor
means the same false-alarm rate whatever the noise's correlation (white noise smoothed
over a GEDI pulse keeps a fifth of its σ, GEDI's correlated noise about half). The front
floor is 6σ: real GEDI windows hold noise excursions (baseline wander, detector tails)
beyond 4σ of the smoothed noise, which a Gaussian would make once in tens of thousands of
windows. A mode is significant when the trough that separates it from its higher
neighbour is at least 3σ of the smoothed noise deep. The noise is measured on the bins
more than three pulse σ away from the signal and from any smoothed value above 3σ (a
faint canopy top below the floors would otherwise pass for noise).

The RH convention differs between the products: GEDI L2A spreads the energy of the
smoothed, noise-subtracted waveform (``rh_smoothed=True, rh_energy="above-noise"``);
LVIS L2 accumulates the recorded counts between the signal end and start, noise level
included (``rh_energy="recorded"``). Cover follows GEDI L2B (ρv/ρg = 1.5, from its
ρv = 0.6 and ρg = 0.4).
"""

from dataclasses import dataclass, fields, replace

#: RH energy conventions: subtract the noise mean, or keep the recorded counts.
RH_ENERGY = ("above-noise", "recorded")
#: Noise sources: measured on the shot's samples, or the file's own noise fields.
NOISE_SOURCES = ("samples", "product")
#: Ground rules: candidates and how deep they are searched (see
#: :mod:`lidarinv.observe.ground_candidates`). GEDI L2A takes the lowest mode of the
#: smoothed waveform above its back floor; LVIS L2 the lowest Gaussian of its
#: decomposition (Hofton, Minster & Blair 2000), which resolves shoulders and is not held
#: to a per-sample floor.
GROUND_RULES = {
    "lowest-mode": {"kinds": ("mode",), "below_back_floor": False},
    "lowest-component": {"kinds": ("mode", "shoulder"), "below_back_floor": True},
}
#: What the floors count σ of: the smoothed noise, or the recorded (raw) noise.
FLOOR_UNITS = ("smoothed", "raw")


@dataclass(frozen=True)
class ProcessingSettings:
    """How one shot is analysed.

    Parameters
    ----------
    smoothing_pulse_widths : float
        Smoothing σ as a multiple of the pulse σ (the pulse FWHM / 2.3548).
    smoothing_bins : float, optional
        Fixed smoothing σ in bins, overriding ``smoothing_pulse_widths``.
    start_sigmas, end_sigmas : float
        Front and back floors, in σ of the noise named by ``floor_units``.
    floor_units : {"smoothed", "raw"}
        The floors count σ of the smoothed noise, or of the recorded noise (as the GEDI
        L2A ATBD defines its thresholds); both σ are measured on the shot.
    prominence_sigmas : float
        Smallest prominence of a mode, in σ of the smoothed noise.
    ground_rule : str
        Key of :data:`GROUND_RULES`: which weaker returns below the lowest prominent
        mode may be the ground (each judged by its energy against the noise).
    min_run : int
        Consecutive bins above a floor that count as signal.
    noise_guard_pulse_widths : float
        Bins nearer than this many pulse σ to the signal extent, or to a smoothed value
        above ``noise_mask_sigmas``, are not used for the noise.
    noise_mask_sigmas : float
        Smoothed values this many σ of the smoothed noise above the mean are faint signal
        (kept out of the noise estimate though below the floors).
    noise_max_lag : int
        Largest lag (bins) of the measured noise autocorrelation.
    noise : {"samples", "product"}
        Measure the noise on the samples (the file's noise fields are then a fallback
        and a cross-check), or take the file's fields.
    rh_energy : {"above-noise", "recorded"}
        RH energy convention (see the module notes).
    rh_smoothed : bool
        RH (and cover) from the smoothed waveform rather than the raw samples.
    rho_ratio : float
        Assumed ρv/ρg for cover.
    min_sensitivity : float
        Quality shots have a sensitivity (largest detectable cover) at least this.
    pavd_layer_m : float (m)
        Thickness of the PAVD layers reported.

    References
    ----------
    Hofton, M. & Blair, J. B. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI
    Transmit and Receive Waveform Processing for L1 and L2 Products*, version 1.0. NASA
    Goddard Space Flight Center, Greenbelt, MD (GEDI L2A's smoothing, thresholds and lowest-
    mode ground).
    Blair, J. B., Rabine, D. L. & Hofton, M. A. (1999). The Laser Vegetation Imaging Sensor:
    a medium-altitude, digitisation-only, airborne laser altimeter for mapping vegetation
    and topography. *ISPRS J. Photogramm. Remote Sens.* 54(2–3), 115–122.
    Hofton, M. A., Minster, J. B. & Blair, J. B. (2000). Decomposition of laser altimeter
    waveforms. *IEEE Trans. Geosci. Remote Sens.* 38(4), 1989–1996 (LVIS L2's ground as the
    lowest Gaussian component).
    Tang, H. & Armston, J. (2019). *Algorithm Theoretical Basis Document (ATBD) for GEDI L2B
    Footprint Canopy Cover and Vertical Profile Metrics*, version 1.0. NASA Goddard Space
    Flight Center, Greenbelt, MD (ρv/ρg of GEDI L2B's cover).
    """

    smoothing_pulse_widths: float = 1.0
    smoothing_bins: float | None = None
    start_sigmas: float = 6.0
    end_sigmas: float = 12.0
    floor_units: str = "smoothed"
    prominence_sigmas: float = 3.0
    ground_rule: str = "lowest-mode"
    min_run: int = 3
    noise_guard_pulse_widths: float = 3.0
    noise_mask_sigmas: float = 3.0
    noise_max_lag: int = 32
    noise: str = "samples"
    rh_energy: str = "above-noise"
    rh_smoothed: bool = True
    rho_ratio: float = 1.5
    min_sensitivity: float = 0.9
    pavd_layer_m: float = 5.0

    def __post_init__(self):
        positive = {
            "smoothing_pulse_widths": self.smoothing_pulse_widths,
            "start_sigmas": self.start_sigmas,
            "end_sigmas": self.end_sigmas,
            "prominence_sigmas": self.prominence_sigmas,
            "rho_ratio": self.rho_ratio,
            "pavd_layer_m": self.pavd_layer_m,
        }
        for name, value in positive.items():
            if not value > 0:
                raise ValueError(f"processing setting {name} must be positive, got {value}")
        if self.smoothing_bins is not None and self.smoothing_bins < 0:
            raise ValueError(f"smoothing_bins must be ≥ 0, got {self.smoothing_bins}")
        if self.min_run < 1 or self.noise_max_lag < 1:
            raise ValueError("min_run and noise_max_lag must be at least 1")
        if self.noise not in NOISE_SOURCES:
            raise ValueError(f"unknown noise source {self.noise!r}; choose from {NOISE_SOURCES}")
        if self.floor_units not in FLOOR_UNITS:
            raise ValueError(f"unknown floor units {self.floor_units!r}; choose {FLOOR_UNITS}")
        if self.ground_rule not in GROUND_RULES:
            raise ValueError(
                f"unknown ground rule {self.ground_rule!r}; choose from {sorted(GROUND_RULES)}"
            )
        if self.rh_energy not in RH_ENERGY:
            raise ValueError(f"unknown RH energy {self.rh_energy!r}; choose from {RH_ENERGY}")


#: Processing defaults per instrument preset name; ``None`` for files of unknown origin.
PROCESSING_DEFAULTS = {
    "gedi": ProcessingSettings(),
    "lvis": ProcessingSettings(
        rh_energy="recorded", rh_smoothed=False, ground_rule="lowest-component"
    ),
    "slicer": ProcessingSettings(),
    None: ProcessingSettings(),
}


def processing_settings(instrument: str | None = None, **overrides) -> ProcessingSettings:
    """The processing defaults of an instrument, with overrides (``None`` values ignored)."""
    key = instrument.lower() if isinstance(instrument, str) else None
    base = PROCESSING_DEFAULTS.get(key, PROCESSING_DEFAULTS[None])
    changes = {k: v for k, v in overrides.items() if v is not None}
    unknown = set(changes) - {f.name for f in fields(ProcessingSettings)}
    if unknown:
        raise TypeError(f"unknown processing setting(s) {sorted(unknown)}")
    return replace(base, **changes)
