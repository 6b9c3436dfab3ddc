"""Terrain context: a ground that leaves its neighbours by more than the terrain allows.

The shots of one track (a GEDI beam, an LVIS flight line) sample continuous terrain, so
a ground retrieved on a canopy layer, or on a noise excursion below the ground, stands
out from its neighbours' grounds. Each shot's ground is compared with a robust plane
fitted to the grounds of its ``NEIGHBOURS`` nearest shots of the same track (positions in
metres from latitude and longitude, the shot itself left out), after subtracting a
per-shot DEM elevation where the file has one (GEDI L1B's ``digital_elevation_model``)
and it makes the track smoother (a smaller residual scale): the DEM then carries the
terrain's large-scale shape, the fit only its local departure; a coarse DEM that is
rougher than the grounds is left out. The
plane is fitted by iteratively reweighted least squares with Tukey's biweight, so one
wrong neighbour does not move it. The allowance is the residual scale σ (1.4826 × the
median absolute departure of the track's shots from their neighbours' planes, or of the
neighbours about their own plane where that is larger: a rough patch), combined with the
shot's own ground uncertainty and the fit's, times the two-sided Gaussian level that
keeps the chance of flagging any shot of the file in such terrain at ``FALSE_ALARM``.
Nothing is tuned to a terrain: a rough or steep track has a larger residual scale and so
a larger allowance.

Shots stay independent: the check only flags (``"terrain outlier"``); the ground itself
is each shot's own.
"""

from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

#: Nearest shots of the same track the local plane is fitted to.
NEIGHBOURS = 8
#: Fewest neighbours with which a shot is checked.
MIN_NEIGHBOURS = 4
#: Probability of flagging any shot of a file whose grounds follow smooth terrain.
FALSE_ALARM = 0.01
#: Tukey biweight tuning constant (95 % efficiency for Gaussian residuals).
BIWEIGHT_C = 4.685
#: Mean Earth radius (m), for local metric coordinates.
EARTH_RADIUS_M = 6_371_000.0
#: Flag set on a shot whose ground leaves its neighbours.
TERRAIN_FLAG = "terrain outlier"


@dataclass(frozen=True)
class TerrainCheck:
    """The terrain check of the shots of one file, in their order (NaN where unchecked).

    Attributes
    ----------
    expected : array (m)
        The ground the neighbours' plane predicts at each shot (DEM added back).
    residual : array (m)
        Ground − expected.
    allowance : array (m)
        Largest |residual| the terrain allows.
    outlier : array of bool
        |residual| > allowance.
    """

    expected: np.ndarray
    residual: np.ndarray
    allowance: np.ndarray
    outlier: np.ndarray


def local_metres(latitude, longitude):
    """East and north offsets (m) from the shots' mean position (equirectangular)."""
    lat, lon = np.radians(latitude), np.radians(longitude)
    known = np.isfinite(lat) & np.isfinite(lon)
    if not known.any():  # a file without positions: nothing to compare
        return np.full(lat.shape, np.nan), np.full(lat.shape, np.nan)
    lat0 = np.mean(lat[known])
    east = EARTH_RADIUS_M * np.cos(lat0) * (lon - np.mean(lon[known]))
    north = EARTH_RADIUS_M * (lat - lat0)
    return east, north


def robust_scale(residuals) -> float:
    """1.4826 × the median absolute residual (σ for Gaussian residuals).

    References
    ----------
    Hampel, F. R. (1974). The influence curve and its role in robust estimation. *J. Am.
    Statist. Assoc.* 69(346), 383–393 (the scaled median absolute deviation).
    """
    return float(1.4826 * np.median(np.abs(residuals)))


def robust_plane(east, north, values, iterations: int = 10):
    """Coefficients (a, b, c) of values ≈ a + b·east + c·north by iteratively reweighted
    least squares with Tukey's biweight (minimum-norm where the points are collinear),
    and the residuals.

    References
    ----------
    Beaton, A. E. & Tukey, J. W. (1974). The fitting of power series, meaning polynomials,
    illustrated on band-spectroscopic data. *Technometrics* 16(2), 147–185 (the biweight).
    Holland, P. W. & Welsch, R. E. (1977). Robust regression using iteratively reweighted
    least-squares. *Commun. Statist. Theory Methods* 6(9), 813–827.
    """
    design = np.column_stack([np.ones_like(east), east, north])
    weights = np.ones_like(values)
    for _ in range(iterations):
        w = np.sqrt(weights)
        coef = np.linalg.lstsq(design * w[:, None], values * w, rcond=1e-10)[0]
        residuals = values - design @ coef
        scale = robust_scale(residuals)
        if scale == 0:
            break
        u = residuals / (BIWEIGHT_C * scale)
        weights = np.where(np.abs(u) < 1, (1 - u * u) ** 2, 0.0)
        if weights.sum() < 3:
            break
    return coef, values - design @ coef


def outlier_level(n_shots: int, false_alarm: float = FALSE_ALARM) -> float:
    """Two-sided Gaussian level z with P(any of ``n_shots`` |residual| > z·σ) ≈
    ``false_alarm``.

    References
    ----------
    Dunn, O. J. (1961). Multiple comparisons among means. *J. Am. Statist. Assoc.* 56(293),
    52–64 (the Bonferroni bound on a family's false-alarm rate).
    """
    return float(norm.isf(0.5 * false_alarm / max(int(n_shots), 1)))


def check_terrain(latitude, longitude, ground, uncertainty=None, track=None, dem=None):
    """Compare each shot's ground with the robust plane of its track neighbours.

    Parameters
    ----------
    latitude, longitude : arrays (degrees)
        Ground positions of the shots.
    ground : array (m)
        Ground elevations (NaN where the shot has none).
    uncertainty : array (m), optional
        1-σ uncertainty of each ground (default 0).
    track : array, optional
        Track label of each shot (beam, flight line); neighbours come from the same track.
    dem : array (m), optional
        DEM elevation at each shot (NaN where missing): the check is then on ground − DEM.

    Returns
    -------
    TerrainCheck
    """
    ground = np.asarray(ground, float)
    n = ground.size
    uncertainty = np.zeros(n) if uncertainty is None else np.asarray(uncertainty, float)
    track = np.zeros(n) if track is None else np.asarray(track, dtype=object)
    dem = np.full(n, np.nan) if dem is None else np.asarray(dem, float)
    east, north = local_metres(np.asarray(latitude, float), np.asarray(longitude, float))
    usable = np.isfinite(ground) & np.isfinite(east) & np.isfinite(north)
    level = outlier_level(int(usable.sum()))
    expected, allowance = np.full(n, np.nan), np.full(n, np.nan)
    for label in {t for t, u in zip(track, usable) if u}:
        members = np.flatnonzero(usable & (track == label))
        # the DEM where every shot of the track has one and it makes the track smoother
        options = [np.zeros(members.size)]
        if np.isfinite(dem[members]).all():
            options.append(dem[members])
        fits = [
            _track_fit(east[members], north[members], ground[members] - base, uncertainty[members])
            for base in options
        ]
        best = int(np.argmin([fit[2] for fit in fits]))
        predicted, spread, _ = fits[best]
        expected[members] = predicted + options[best]
        allowance[members] = level * spread
    residual = ground - expected
    outlier = np.isfinite(residual) & (np.abs(residual) > allowance)
    return TerrainCheck(expected, residual, allowance, outlier)


def _track_fit(east, north, relief, uncertainty):
    """Each shot's relief predicted by its neighbours' robust plane, the σ of its
    departure (residual scale, the fit's error, the shot's own uncertainty), and the
    track's pooled residual scale (NaN where too few shots)."""
    n = relief.size
    predicted, local, count = np.full(n, np.nan), np.full(n, np.nan), np.zeros(n)
    for i in range(n):
        others = np.flatnonzero(np.arange(n) != i)
        if others.size < MIN_NEIGHBOURS:
            continue
        distance = np.hypot(east[others] - east[i], north[others] - north[i])
        near = others[np.argsort(distance)[:NEIGHBOURS]]
        coef, residuals = robust_plane(east[near] - east[i], north[near] - north[i], relief[near])
        predicted[i], local[i], count[i] = coef[0], robust_scale(residuals), near.size
    checked = np.isfinite(predicted)
    if not checked.any():
        return predicted, np.full(n, np.nan), np.inf
    # the track's scale: its shots' departures from their neighbours' planes
    pooled = robust_scale(relief[checked] - predicted[checked])
    scale = np.maximum(pooled, local)
    # the prediction's own error: σ·√(p / K) for p = 3 coefficients from K shots
    with np.errstate(divide="ignore", invalid="ignore"):
        variance = scale**2 * (1.0 + 3.0 / count) + np.nan_to_num(uncertainty) ** 2
    return predicted, np.sqrt(variance), pooled


def shot_track(metadata: dict):
    """A shot's track label from the reader's metadata (GEDI beam, LVIS LFID)."""
    return metadata.get("beam", metadata.get("lfid", ""))


def flag_terrain(results, dem=None) -> TerrainCheck:
    """Run :func:`check_terrain` over the shot analyses of one file and record it on each
    (``terrain_expected``, ``terrain_residual``, ``terrain_allowance``, the flag
    ``"terrain outlier"``, which takes a shot out of the quality set).

    Parameters
    ----------
    results : list of ShotAnalysis
    dem : array (m), optional
        DEM elevation per result (see :func:`file_dem`).
    """
    check = check_terrain(
        [r.latitude for r in results],
        [r.longitude for r in results],
        [r.ground if r.ok else np.nan for r in results],
        [r.ground_uncertainty for r in results],
        track=[str(shot_track(r.metadata)) for r in results],
        dem=dem,
    )
    for i, result in enumerate(results):
        result.terrain_expected = float(check.expected[i])
        result.terrain_residual = float(check.residual[i])
        result.terrain_allowance = float(check.allowance[i])
        if check.outlier[i]:
            result.flags.append(TERRAIN_FLAG)
            result.quality = False
    return check


def file_dem(path, results) -> np.ndarray | None:
    """DEM elevation (m) per result where the file carries one per shot (GEDI L1B
    ``BEAMxxxx/geolocation/digital_elevation_model``, located by the reader's ``beam``
    and ``index`` metadata); ``None`` for files without."""
    import h5py

    out = np.full(len(results), np.nan)
    with h5py.File(path, "r") as handle:
        for i, result in enumerate(results):
            beam, index = result.metadata.get("beam"), result.metadata.get("index")
            name = f"{beam}/geolocation/digital_elevation_model"
            if beam is None or index is None or name not in handle:
                continue
            value = float(handle[name][int(index)])
            out[i] = value if abs(value) < 1e4 else np.nan  # fill values (−999999)
    return out if np.isfinite(out).any() else None
