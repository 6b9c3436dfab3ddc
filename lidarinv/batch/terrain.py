"""Terrain context for a batch over one file: the shots' grounds against their track
neighbours', as ``lidarinv metrics`` checks them (:mod:`lidarinv.observe.terrain`).

:func:`terrain_context` analyses every shot of the file (the analysis the inversion
starts from), fits each track's robust local planes and keeps, per shot, the ground the
neighbours predict, its σ, and the flag of a shot whose ground leaves them.
:class:`WithTerrain` wraps an inversion so that each result carries its shot's flag and,
as an option (off by default), takes its ground prior from the terrain fit. Shots stay
independent unless that option is asked for.
"""

from dataclasses import dataclass, replace

import numpy as np

from lidarinv.observe.analyse import analyse
from lidarinv.observe.instrument import shot_instrument
from lidarinv.observe.observation import Observation
from lidarinv.observe.terrain import TERRAIN_FLAG, file_dem, flag_terrain, outlier_level

from .store import group_name


@dataclass(frozen=True)
class TerrainContext:
    """Per shot (keyed by :func:`~lidarinv.batch.store.group_name`) what its track's
    terrain says.

    Attributes
    ----------
    expected : dict of name → (float, float) (m)
        The ground the neighbours' plane predicts and its σ (the allowance over the
        file's outlier level), for every shot checked.
    flags : dict of name → str
        The flag of each shot whose ground leaves its neighbours.
    """

    expected: dict
    flags: dict


def terrain_context(path, observations, instrument=None, processing=None) -> TerrainContext:
    """The terrain check of a file's shots.

    Parameters
    ----------
    path : path or None
        The waveform file (for a per-shot DEM where it carries one); None for no DEM.
    observations : iterable of Observation or ShotError
        Its shots; unreadable ones are left out.
    instrument : str, optional
        Instrument preset overriding the file's.
    processing : ProcessingSettings, optional
        How shots are analysed (the instrument's defaults if omitted).

    Returns
    -------
    TerrainContext
    """
    results = []
    for item in observations:
        if not isinstance(item, Observation):
            continue
        try:
            chosen = shot_instrument(item, instrument)
            results.append(analyse(item, processing, instrument=chosen, metrics=False))
        except ValueError:  # e.g. no instrument named: the inversion reports it
            continue
    if not results:
        return TerrainContext({}, {})
    check = flag_terrain(results, None if path is None else file_dem(path, results))
    level = outlier_level(int(np.isfinite(check.residual).sum()))
    expected, flags = {}, {}
    for i, result in enumerate(results):
        name = group_name(result.shot_id)
        if np.isfinite(check.expected[i]) and np.isfinite(check.allowance[i]):
            expected[name] = (float(check.expected[i]), float(check.allowance[i] / level))
        if check.outlier[i]:
            flags[name] = (
                f"{TERRAIN_FLAG}: the analysis's ground {result.ground:.2f} m leaves its track "
                f"neighbours' {check.expected[i]:.2f} m by {check.residual[i]:+.2f} m (the "
                f"terrain allows {check.allowance[i]:.2f} m)"
            )
    return TerrainContext(expected, flags)


def terrain_ground_prior(expected, sigma, settings):
    """``settings`` with the ground's prior taken from the terrain fit: N(expected, σ²)
    truncated at ±6σ (the analysis's registration of a ground peak: the pulse's offset, a
    fraction of a metre, stays within σ).

    Parameters
    ----------
    expected, sigma : float (m)
    settings : InversionSettings or None

    Returns
    -------
    InversionSettings
    """
    from lidarinv.inference import InversionSettings
    from lidarinv.inference.model.priors import TruncatedNormal

    settings = InversionSettings() if settings is None else settings
    prior = TruncatedNormal(expected, sigma, expected - 6.0 * sigma, expected + 6.0 * sigma)
    entry = {**settings.priors.get("ground_elevation", {}), "prior": prior}
    return replace(settings, priors={**settings.priors, "ground_elevation": entry})


@dataclass(frozen=True)
class WithTerrain:
    """An inversion whose results carry their shot's terrain flag and, with
    ``ground_prior``, whose ground prior is the terrain fit's; picklable where ``invert``
    is.

    Parameters
    ----------
    invert : callable
        ``invert(observation, settings, rng=..., progress=...)``.
    context : TerrainContext
    ground_prior : bool
        Take each checked shot's ground prior from the terrain fit
        (:func:`terrain_ground_prior`).
    """

    invert: object
    context: TerrainContext
    ground_prior: bool = False

    def __call__(self, observation, settings=None, *, rng=None, progress=False):
        name = group_name(observation.shot_id)
        if self.ground_prior and name in self.context.expected:
            settings = terrain_ground_prior(*self.context.expected[name], settings)
        result = self.invert(observation, settings, rng=rng, progress=progress)
        if name in self.context.flags:
            result.flags.append(self.context.flags[name])
        return result
