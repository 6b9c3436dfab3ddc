"""Truth stands from outside the inversion's model family, for ``studies/recovery.py``.

The inversion describes a footprint by a stationary Poisson stand of one truncated-normal
height cohort with crown radius 0.1·h. The generators here draw explicit stem maps that
break those assumptions, each with its parameters drawn at random from the
``numpy.random.Generator`` it is given (:data:`STAND_KINDS`):

- ``weibull`` and ``lognormal``: one cohort of Weibull or lognormal heights (skewed,
  unbounded: an occasional tall stem);
- ``two-storey``: two truncated-normal height cohorts, an overstorey and a lower storey;
- ``emergent``: a lower canopy with one emergent tree 8–18 m above its top, within 1 σf
  of the beam centre;
- ``clumped``: stems of a Thomas cluster process (:data:`forward.realise.POINT_PATTERNS`);
- ``sparse``: a savanna-like stand (20–120 stems/ha, 3–10 m, wide crowns, a grass layer),
  crown cover mostly below 0.35;
- ``dense``: 1500–3500 stems/ha on a regular (hard-core) pattern, crown cover near 1.

Crown length ratio, crown shapes, FAVD, the understory and ρv/ρg are drawn from the
ranges of recovery.py's own stands unless a kind says otherwise. A shot
(:func:`out_of_family_shot`) is simulated with the explicit engine at its defaults
(:func:`lidarinv.examples.explicit_shot`) and observed with GEDI-like noise, as
recovery.py does for its in-family stands.

**Truths comparable across families.** The inversion's ``top_height`` is the upper end
of its truncated-normal height family and has no counterpart in a Weibull stand, and its
``cover`` is a property of a stationary stand. Out-of-family truths are therefore
properties of the simulated footprint, compared with the posterior quantities that
estimate them:

- ``footprint_top_height``: the tallest stem within 2 σf of the beam centre, against the
  posterior's tallest stem drawn within the same disc
  (:func:`lidarinv.inference.results.collect.footprint_top_height`); the "top height" of the
  issue's target;
- ``rh98``: RH98 of the true noise-free waveform, against the posterior's RH98 of its
  model waveform (both in the GEDI L2A convention);
- ``cover``: the footprint's crown cover, the footprint-weighted fraction of the ground
  under at least one crown (:func:`forward.footprint.footprint_crown_cover`), against the
  posterior's crown cover, whose expectation over a stationary stand's footprints it is,
  and against the posterior's ``footprint_cover``, the same footprint quantity of a
  realisation of each sample's stand (:func:`lidarinv.inference.passes.realisations.
  footprint_cover`), which can be 0 (no crown within reach) or 1 (every node covered)
  as the truth can; the "cover" of the target;
- ``gap_cover``: 1 − P̄(0)/P_u of the simulated footprint, against the posterior's
  ``gap_cover``, the quantity the waveform's ground energy measures (and GEDI L2B
  reports);
- ``ground_elevation``: 0 at the beam centre (flat ground);
- ``gain`` (per unit ground reflectance) as for the in-family stands.

Quantities of the stand's distribution (PAI, mean height, ``top_height``) are left out
(NaN), so they drop out of the coverage tables.
"""

from functools import partial

import numpy as np

from forward.footprint import footprint_crown_cover
from forward.instrument import instrument_preset
from forward.realise import realise
from forward.stand import Stand
from forward.stand_params import StandParams
from lidarinv.examples import ShotRecipe, explicit_shot

#: Observation settings of every shot: GEDI, baseline and noise σ (DN) as in recovery.py.
INSTRUMENT, BASELINE, NOISE_SIGMA = "gedi", 50.0, 2.0

#: The window reaches this far below the ground and above the footprint's tallest crown
#: (m), as :func:`lidarinv.examples.synthetic_shot`'s.
BELOW_GROUND_M, ABOVE_TOP_M = 12.0, 18.0


def _canopy(rng, **stand) -> StandParams:
    """Stand parameters with crowns, understory and reflectances drawn as recovery.py's
    in-family stands; ``stand`` sets heights and density and may override any field."""
    cone = rng.uniform(0.0, 1.0)
    fields = {
        "height_family": "truncnorm",
        "height_truncation": 2.0,
        "shape_mix": {"cone": cone, "ellipsoid": 1.0 - cone},
        "crown_length_ratio": rng.uniform(0.3, 0.7),
        "favd": rng.uniform(0.3, 1.2),
        "understory_height": rng.uniform(0.5, 2.0),
        "understory_lai": rng.uniform(0.0, 0.8),
        "ground_reflectance": 0.3,
        "canopy_reflectance": 0.3 * float(np.clip(rng.normal(1.5, 0.3), 0.8, 2.5)),
    }
    return StandParams(**{**fields, **stand})


def skewed_heights(rng, side, family):
    """One cohort of Weibull or lognormal heights (``family``; mean 8–25 m, sd 2–6 m) on a
    Poisson pattern."""
    params = _canopy(
        rng,
        density=rng.uniform(200.0, 1500.0),
        height_family=family,
        height_mean=rng.uniform(8.0, 25.0),
        height_sd=rng.uniform(2.0, 6.0),
    )
    return params, realise(params, side, rng)


def two_storeys(rng, side):
    """An overstorey (mean 18–30 m, sd 1–3 m) over a lower storey (mean 4–9 m, sd
    0.5–1.5 m) holding 30–70 % of the stems, on a Poisson pattern: the storeys' means
    lie at least 9 m and 4.5 of their sds apart, so the height histogram has two modes."""
    params = _canopy(
        rng,
        density=rng.uniform(400.0, 1500.0),
        height_mean=rng.uniform(18.0, 30.0),
        height_sd=rng.uniform(1.0, 3.0),
        cohort2_fraction=rng.uniform(0.3, 0.7),
        cohort2_height_mean=rng.uniform(4.0, 9.0),
        cohort2_height_sd=rng.uniform(0.5, 1.5),
    )
    return params, realise(params, side, rng)


def emergent_tree(rng, side):
    """A lower canopy (mean 8–15 m, sd 1–2.5 m) and one emergent tree 8–18 m above the
    canopy's upper end (mean + 2 sd), placed uniformly within 1 σf of the plot centre."""
    params = _canopy(
        rng,
        density=rng.uniform(300.0, 1200.0),
        height_mean=rng.uniform(8.0, 15.0),
        height_sd=rng.uniform(1.0, 2.5),
    )
    canopy = realise(params, side, rng)
    height = params.height_mean + 2.0 * params.height_sd + rng.uniform(8.0, 18.0)
    radius = instrument_preset(INSTRUMENT).footprint_sigma_m * np.sqrt(rng.uniform())
    angle = rng.uniform(0.0, 2.0 * np.pi)
    tree = Stand.from_arrays(
        x=[side / 2 + radius * np.cos(angle)],
        y=[side / 2 + radius * np.sin(angle)],
        height=[height],
        crown_length=[params.crown_length(height)],
        crown_radius=[params.crown_radius(height)],
        shape=str(rng.choice(["cone", "ellipsoid"])),
        favd=params.favd,
    )
    return params, _join(canopy, tree)


def clumped_stems(rng, side):
    """Stems of a Thomas cluster process (5–15 stems a cluster, cluster sd 1–3 m), one
    truncated-normal cohort (mean 8–25 m, sd 1–4 m)."""
    params = _canopy(
        rng,
        density=rng.uniform(200.0, 1500.0),
        height_mean=rng.uniform(8.0, 25.0),
        height_sd=rng.uniform(1.0, 4.0),
    )
    options = {"cluster_size": rng.uniform(5.0, 15.0), "cluster_sd": rng.uniform(1.0, 3.0)}
    return params, realise(params, side, rng, pattern="thomas", **options)


def sparse_savanna(rng, side):
    """A savanna-like stand: 20–120 stems/ha of 3–10 m (sd 0.5–2.5 m) with wide crowns
    (radius 0.5–1.5 m + 0.1–0.2·h) over a grass layer (0.3–1 m, LAI 0.2–1)."""
    params = _canopy(
        rng,
        density=rng.uniform(20.0, 120.0),
        height_mean=rng.uniform(3.0, 10.0),
        height_sd=rng.uniform(0.5, 2.5),
        crown_radius_intercept=rng.uniform(0.5, 1.5),
        crown_radius_slope=rng.uniform(0.1, 0.2),
        understory_height=rng.uniform(0.3, 1.0),
        understory_lai=rng.uniform(0.2, 1.0),
    )
    return params, realise(params, side, rng)


def dense_stand(rng, side):
    """1500–3500 stems/ha (mean 15–30 m, sd 1–4 m) on a hard-core pattern (stems at
    least 0.8–1.2 m apart)."""
    params = _canopy(
        rng,
        density=rng.uniform(1500.0, 3500.0),
        height_mean=rng.uniform(15.0, 30.0),
        height_sd=rng.uniform(1.0, 4.0),
    )
    spacing = rng.uniform(0.8, 1.2)
    return params, realise(params, side, rng, pattern="hardcore", min_distance=spacing)


#: Out-of-family stand kinds: ``kind(rng, side) -> (params, stand)``, ``params`` holding
#: the ground reflectance, ρv and the understory, ``stand`` the stem map on a square plot
#: of the given side (m) seen at its centre.
STAND_KINDS = {
    "weibull": partial(skewed_heights, family="weibull"),
    "lognormal": partial(skewed_heights, family="lognormal"),
    "two-storey": two_storeys,
    "emergent": emergent_tree,
    "clumped": clumped_stems,
    "sparse": sparse_savanna,
    "dense": dense_stand,
}


def _join(a: Stand, b: Stand) -> Stand:
    columns = ("x", "y", "height", "crown_length", "crown_radius", "shape", "favd")
    return Stand(**{c: np.concatenate([getattr(a, c), getattr(b, c)]) for c in columns})


def draw_scene(kind, rng):
    """One stand of a kind on a plot three footprint diameters wide.

    Parameters
    ----------
    kind : str
        Key of :data:`STAND_KINDS`.
    rng : numpy.random.Generator

    Returns
    -------
    params : StandParams
    stand : forward.stand.Stand
    centre : (float, float) (m)
        The beam centre, the plot's centre.
    """
    try:
        generator = STAND_KINDS[kind]
    except KeyError:
        raise ValueError(f"unknown stand kind {kind!r}; known: {sorted(STAND_KINDS)}") from None
    side = 3.0 * instrument_preset(INSTRUMENT).footprint_diameter_m
    params, stand = generator(rng, side)
    return params, stand, (side / 2, side / 2)


def out_of_family_shot(rng, index, kind=None):
    """One GEDI-like shot of an out-of-family stand.

    Parameters
    ----------
    rng : numpy.random.Generator
    index : int
        The shot's id; it picks the kind in turn (``index`` modulo the number of kinds)
        unless ``kind`` is given.
    kind : str, optional

    Returns
    -------
    lidarinv.observe.observation.Observation
        With the footprint's truths (module docstring), the stand ``kind`` and the
        drawn gain in ``truth``.
    """
    kind = list(STAND_KINDS)[index % len(STAND_KINDS)] if kind is None else kind
    params, stand, centre = draw_scene(kind, rng)
    instrument = instrument_preset(INSTRUMENT)
    recipe = ShotRecipe(params, rng.uniform(4000.0, 12000.0), BASELINE, NOISE_SIGMA, INSTRUMENT)
    near = np.hypot(stand.x - centre[0], stand.y - centre[1]) <= instrument.footprint_diameter_m
    top = max(float(np.max(stand.height[near], initial=0.0)), params.understory_height)
    heights = np.arange(-BELOW_GROUND_M, top + ABOVE_TOP_M, instrument.bin_height)
    obs = explicit_shot(recipe, stand, centre, heights, rng, shot_id=index)
    sigma = instrument.footprint_sigma_m
    obs.truth["cover"] = footprint_crown_cover(stand, centre, sigma)
    obs.truth["kind"] = kind
    return obs
