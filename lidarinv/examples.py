"""Built-in example shots: synthetic observations of example stands.

``lidarinv invert --example NAME`` inverts the recipe NAME of :data:`SYNTHETIC_SHOTS`. A
shot is drawn from an **explicit** random stand (``forward.realise``) run through the
explicit 3-D engine, then through the observation model, so that inverting it with the
expected-waveform model is not an inverse crime; ``explicit=False`` gives the inverse
crime (the expected waveform itself) for comparison. The stands are those of
:data:`forward.examples.EXAMPLE_STANDS`; the tests and studies draw their synthetic shots
here too.
"""

from dataclasses import dataclass

import numpy as np

from forward import derived
from forward.examples import EXAMPLE_STANDS
from forward.expected import ExpectedWaveformModel
from forward.explicit import WaveformSimulator
from forward.instrument import instrument_preset
from forward.realise import realise, scene_extras
from forward.stand_params import StandParams
from lidarinv.inference.model.stand import TOP_SDS
from lidarinv.inference.model.tallest_stem import tallest_stem_within
from lidarinv.observe.metrics import rh_metrics
from lidarinv.observe.simulate import observe


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


#: Built-in synthetic shots: GEDI-like observations of :data:`forward.examples.EXAMPLE_STANDS`.
SYNTHETIC_SHOTS = {name: ShotRecipe(params) for name, params in EXAMPLE_STANDS.items()}


def true_values(params: StandParams, gain: float, baseline: float, noise_sigma: float) -> dict:
    """Inversion-parameter values of a stand (the truth of a synthetic shot).

    Parameters
    ----------
    params : StandParams
        A single-cohort stand of cones and ellipsoids.
    gain : float (DN per unit apparent reflectance)
    baseline, noise_sigma : float (DN)

    Returns
    -------
    dict
        The default parameterisation's values (cover, PAI, top height, …, the gain per
        unit ground reflectance, ρv/ρg) and derived quantities (mean height, LAI, crown
        volume) of :mod:`forward.derived`.
    """
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
    """The tallest stem of an explicit stand within the footprint's 1/e² radius.

    Parameters
    ----------
    stand : forward.stand.Stand
    centre : (float, float) (m)
    footprint_sigma_m : float (m)

    Returns
    -------
    float (m)
        Its height; 0 if none (:func:`lidarinv.inference.model.tallest_stem.
        tallest_stem_within`).
    """
    return tallest_stem_within(stand, centre, footprint_sigma_m)[0]


def footprint_truths(stand, centre, waveform, instrument, understory=None) -> dict:
    """What a footprint of an explicit stand truly holds, in the posterior's own terms.

    Parameters
    ----------
    stand : forward.stand.Stand
    centre : (float, float) (m)
        The beam centre in stand coordinates.
    waveform : forward.explicit.Waveform
        The footprint's noise-free waveform, on an axis holding its whole return.
    instrument : forward.instrument.Instrument
    understory : forward.scene.UniformUnderstory, optional

    Returns
    -------
    dict
        ``footprint_top_height``: the tallest stem within 2σf (:func:`tallest_within`),
        the posterior's ``footprint_top_height``; ``rh98``: RH98 of the noise-free
        waveform above the ground at the beam centre in the GEDI L2A convention
        (:func:`lidarinv.observe.metrics.rh_metrics`), the posterior's ``rh98`` of the
        model waveform; ``gap_cover``: 1 − P̄(0)/P_u, the footprint-mean gap through
        the tree crowns (P_u the uniform understory's own gap), the posterior's
        ``gap_cover``.
    """
    lai = 0.0 if understory is None else understory.lai
    understory_gap = np.exp(-instrument.extinction_per_favd * lai)
    rh98 = rh_metrics(waveform.samples, waveform.heights, 0.0, percentiles=[98.0])[0]
    return {
        "footprint_top_height": tallest_within(stand, centre, instrument.footprint_sigma_m),
        "rh98": float(rh98),
        "gap_cover": float(1.0 - waveform.ground_gap / understory_gap),
    }


def explicit_shot(recipe: ShotRecipe, stand, centre, heights, rng, shot_id=0):
    """One noisy observation of a footprint over an explicit stand.

    Parameters
    ----------
    recipe : ShotRecipe
        Observation settings; its ``params`` give the ground reflectance, ρv and the
        uniform understory (:func:`forward.realise.scene_extras`), not the trees.
    stand : forward.stand.Stand
    centre : (float, float) (m)
        The beam centre in stand coordinates; the ground there is at 0.
    heights : array (m)
        Bin heights above the ground.
    rng : numpy.random.Generator
    shot_id : int or str

    Returns
    -------
    lidarinv.observe.observation.Observation
        With the ground elevation (0), the gain per unit ground reflectance, ρv/ρg and
        :func:`footprint_truths` in ``truth``.
    """
    instrument = instrument_preset(recipe.instrument)
    ground, understory, rho_v = scene_extras(recipe.params)
    waveform = WaveformSimulator(instrument).simulate(
        stand, centre, heights, ground, rho_v, understory
    )
    obs = _observe(recipe, waveform.samples, heights, rng, shot_id)
    obs.truth.update(footprint_truths(stand, centre, waveform, instrument, understory))
    obs.truth["gain"] = recipe.gain * ground.reflectance
    obs.truth["rho_ratio"] = rho_v / ground.reflectance
    return obs


def _observe(recipe: ShotRecipe, signal, heights, rng, shot_id):
    """GEDI-like observation of a noise-free waveform (:func:`lidarinv.observe.simulate.
    observe`) with the recipe's gain, baseline and noise, the ground at 0."""
    obs = observe(
        signal,
        heights=heights,
        gain=recipe.gain,
        baseline=recipe.baseline,
        noise_sigma=recipe.noise_sigma,
        rng=rng,
        shot_id=shot_id,
        instrument=recipe.instrument,
    )
    obs.truth.pop("signal", None)
    obs.truth["ground_elevation"] = 0.0
    return obs


def synthetic_shot(
    recipe: ShotRecipe, rng: np.random.Generator, explicit=True, shot_id=0, heights=None
):
    """One noisy observation of a recipe's stand.

    Parameters
    ----------
    recipe : ShotRecipe
    rng : numpy.random.Generator
    explicit : bool
        Observe one random realisation of the stand on a plot 3 footprint diameters wide,
        seen at its centre (:func:`explicit_shot`); otherwise the expected waveform.
    shot_id : int or str
    heights : array (m), optional
        Bin heights above the ground; by default from 12 m below the ground to 18 m above
        the top height, in the instrument's bins.

    Returns
    -------
    lidarinv.observe.observation.Observation
        With the true parameter values (:func:`true_values`), the ground elevation (0) and
        the footprint's :func:`footprint_truths` (explicit stands only; NaN otherwise) in
        ``truth``.
    """
    p = recipe.params
    instrument = instrument_preset(recipe.instrument)
    top = p.height_mean + TOP_SDS * p.height_sd
    if heights is None:
        heights = np.arange(-12.0, top + 18.0, instrument.bin_height)
    if explicit:
        side = 3.0 * instrument.footprint_diameter_m
        stand = realise(p, side, rng)
        obs = explicit_shot(recipe, stand, (side / 2, side / 2), heights, rng, shot_id)
    else:
        model = ExpectedWaveformModel(instrument, heights, p)
        obs = _observe(recipe, model(model.vector(p))[0], heights, rng, shot_id)
        # the expected stand holds no particular trees
        obs.truth.update(dict.fromkeys(("footprint_top_height", "rh98", "gap_cover"), np.nan))
    obs.truth.update(true_values(p, recipe.gain, recipe.baseline, recipe.noise_sigma))
    return obs
