"""Synthetic shots for examples, tests and recovery studies.

A shot is drawn from an **explicit** random stand (``forward.realise``) run through the
explicit 3-D engine, then through the observation model, so that inverting it with the
expected-waveform model is not an inverse crime. ``explicit=False`` gives the inverse
crime (the expected waveform itself) for comparison.
"""

from dataclasses import dataclass

import numpy as np

from forward import derived
from forward.engine import WaveformSimulator
from forward.expected import ExpectedWaveformModel
from forward.instrument import instrument_preset
from forward.realise import realise, scene_extras
from forward.stand_params import StandParams
from lidarinv.observe.simulate import observe

from .stand_mapping import TALLEST_STEM_RADIUS_SIGMAS, TOP_SDS


@dataclass(frozen=True)
class ShotRecipe:
    """Stand and observation settings of a synthetic shot.

    Parameters
    ----------
    params : StandParams
        Single-cohort, truncated-normal heights truncated at ±2 sd (the default
        parameterisation).
    gain : float (DN per unit apparent reflectance)
    baseline, noise_sigma : float (DN)
    instrument : str
        Instrument preset.
    """

    params: StandParams
    gain: float = 8000.0
    baseline: float = 50.0
    noise_sigma: float = 2.0
    instrument: str = "gedi"


#: Built-in synthetic shots.
SYNTHETIC_SHOTS = {
    "gedi-mixed": ShotRecipe(
        StandParams(
            density=600.0,
            height_mean=16.0,
            height_sd=3.0,
            height_family="truncnorm",
            height_truncation=TOP_SDS,
            shape_mix={"cone": 0.6, "ellipsoid": 0.4},
            favd=0.6,
            understory_height=1.0,
            understory_lai=0.3,
            canopy_reflectance=0.45,
            ground_reflectance=0.3,
        )
    ),
}


def true_values(params: StandParams, gain: float, baseline: float, noise_sigma: float) -> dict:
    """Inversion-parameter values of a stand (the truth of a synthetic shot)."""
    mix = dict(zip(("cone", "ellipsoid"), params.shape_mix[:2]))
    return {
        "cover": derived.canopy_cover(params),
        "pai": derived.leaf_area_index(params) - params.understory_lai,
        "top_height": params.height_mean + TOP_SDS * params.height_sd,
        "height_sd": params.height_sd,
        "crown_length_ratio": params.crown_length_ratio,
        "cone_fraction": mix["cone"],
        "understory_height": params.understory_height,
        "understory_lai": params.understory_lai,
        "gain": gain * params.ground_reflectance,
        "baseline": baseline,
        "noise_sigma": noise_sigma,
        "rho_ratio": params.canopy_reflectance / params.ground_reflectance,
        "mean_height": derived.mean_height(params),
        "lai": derived.leaf_area_index(params),
        "crown_volume": derived.crown_volume_per_ha(params),
    }


def tallest_within(stand, centre, footprint_sigma_m) -> float:
    """Height (m) of the tallest stem within the footprint's 1/e² radius
    (:data:`.stand_mapping.TALLEST_STEM_RADIUS_SIGMAS`·σf) of ``centre``; 0 if none."""
    return tallest_stem_within(stand, centre, footprint_sigma_m)[0]


def tallest_stem_within(stand, centre, footprint_sigma_m) -> tuple[float, float]:
    """Height (m) of the tallest stem within the footprint's 1/e² radius R of ``centre``
    and its squared distance from it over R²; (0, NaN) if none."""
    radius = TALLEST_STEM_RADIUS_SIGMAS * footprint_sigma_m
    r2 = ((stand.x - centre[0]) ** 2 + (stand.y - centre[1]) ** 2) / radius**2
    inside = np.flatnonzero(r2 <= 1.0)
    if inside.size == 0:
        return 0.0, np.nan
    tallest = inside[np.argmax(stand.height[inside])]
    return float(stand.height[tallest]), float(r2[tallest])


def synthetic_shot(
    recipe: ShotRecipe, rng: np.random.Generator, explicit=True, shot_id=0, heights=None
):
    """One noisy observation of the recipe's stand (heights m above ground).

    With ``explicit`` the stand is one random realisation on a plot 3 footprint diameters
    wide, seen at its centre; otherwise the expected waveform is observed.
    """
    p = recipe.params
    instrument = instrument_preset(recipe.instrument)
    top = p.height_mean + TOP_SDS * p.height_sd
    if heights is None:
        heights = np.arange(-12.0, top + 18.0, instrument.bin_height)
    if explicit:
        side = 3.0 * instrument.footprint_diameter_m
        stand = realise(p, side, rng)
        ground, understory, rho_v = scene_extras(p)
        waveform = WaveformSimulator(instrument).simulate(
            stand, (side / 2, side / 2), heights, ground, rho_v, understory
        )
        signal = waveform.samples
        footprint_top = tallest_within(stand, (side / 2, side / 2), instrument.footprint_sigma_m)
    else:
        model = ExpectedWaveformModel(instrument, heights, p)
        signal = model(model.vector(p))[0]
        footprint_top = np.nan  # the expected stand holds no particular trees
    obs = observe(
        signal,
        heights=heights,
        gain=recipe.gain,
        baseline=recipe.baseline,
        noise_sigma=recipe.noise_sigma,
        rng=rng,
        shot_id=shot_id,
    )
    obs.truth.update(true_values(p, recipe.gain, recipe.baseline, recipe.noise_sigma))
    obs.truth["ground_elevation"] = 0.0
    obs.truth["footprint_top_height"] = footprint_top
    obs.truth.pop("signal", None)
    return obs
