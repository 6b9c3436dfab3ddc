"""The priors file of an inversion (TOML): its reader.

Each table names a parameter of the inversion (:mod:`lidarinv.inference.model.parameters`)
and gives its prior, a fixed value, or ``free = true``; a few tables set inversion
settings instead (:data:`SETTINGS_TABLES`), read with the parameters' by
:meth:`lidarinv.inference.InversionSettings.from_priors_file`.
"""

import tomllib

import numpy as np

from .likelihood.discrepancy import DISCREPANCY_MODELS
from .model.parameters import COHORT2, LATENT, NUISANCE, STRUCTURE
from .model.priors import make_prior


def read_toml(path) -> dict:
    """The tables of a TOML file.

    Parameters
    ----------
    path : path

    Returns
    -------
    dict

    Raises
    ------
    ValueError
        For invalid TOML, naming the file.
    """
    try:
        with open(path, "rb") as handle:
            return tomllib.load(handle)
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{path}: not valid TOML: {error}") from None


def read_priors_file(path) -> dict:
    """The parameters' prior overrides in a TOML priors file.

    Each table is a parameter name; keys ``kind`` (uniform, log-uniform,
    truncated-normal) with its numbers, and/or ``fixed = value``, or ``free = true`` to
    sample a parameter that is fixed by default::

        [top_height]
        kind = "uniform"
        lower = 5.0
        upper = 40.0

        [understory_lai]
        fixed = 0.0

    Tables that set inversion settings rather than a prior (``[favd]``, ``[ground]``,
    ``[discrepancy]``: :data:`SETTINGS_TABLES`) are left to
    :meth:`lidarinv.inference.InversionSettings.from_priors_file`, which reads both. A
    table for either latent of the tallest stem (e.g. ``[tallest_stem_height]`` with
    ``free = true``) conditions each footprint on its tallest stem.

    Parameters
    ----------
    path : path

    Returns
    -------
    dict
        ``{name: {"fixed": value or None, "prior": prior}}`` with the keys each table sets.

    Raises
    ------
    ValueError
        For invalid TOML, an unknown table or a bad prior, naming the file and table.
    """
    table = read_toml(path)
    known = set(STRUCTURE) | set(COHORT2) | set(NUISANCE) | set(LATENT) | set(SETTINGS_TABLES)
    unknown = sorted(set(table) - known)
    if unknown:
        raise ValueError(f"{path}: unknown parameter(s) {unknown}; known: {sorted(known)}")
    changes = {}
    for name, spec in table.items():
        if not isinstance(spec, dict):
            raise ValueError(f"{path}: [{name}] must be a table")
        if name in SETTINGS_TABLES:
            continue
        spec = dict(spec)
        change = {}
        if "fixed" in spec:
            value = float(spec.pop("fixed"))
            if not np.isfinite(value):
                raise ValueError(f"{path}: [{name}] fixed value must be finite")
            change["fixed"] = value
        elif spec.pop("free", False) or spec:
            change["fixed"] = None
        if spec:
            try:
                change["prior"] = make_prior(spec)
            except ValueError as error:
                raise ValueError(f"{path}: [{name}] {error}") from None
        changes[name] = change
    return changes


def read_settings_tables(path) -> dict:
    """The settings tables of a priors file (:data:`SETTINGS_TABLES`), checked.

    Parameters
    ----------
    path : path
        TOML priors file.

    Returns
    -------
    dict
        ``"favd"``: ``{"range": (lower, upper)}`` (m²/m³); ``"ground"``:
        ``{"prior_sd": value}`` (m); ``"discrepancy"``: any of ``model``, ``eta`` and
        ``count``; for the tables the file has.

    Raises
    ------
    ValueError
        Naming the file, the table and the problem.
    """
    table = read_toml(path)
    return {
        name: reader(path, table[name]) for name, reader in SETTINGS_TABLES.items() if name in table
    }


def _favd_range(path, spec) -> dict:
    unknown = sorted(set(spec) - {"lower", "upper"})
    if unknown:
        raise ValueError(f"{path}: [favd] takes lower and upper (m2/m3), not {unknown}")
    low, high = float(spec.get("lower", 0.0)), float(spec.get("upper", np.inf))
    if not (0.0 <= low < high):
        raise ValueError(f"{path}: [favd] needs 0 <= lower < upper, got {low}, {high}")
    return {"range": (low, high)}


def _ground_prior(path, spec) -> dict:
    unknown = sorted(set(spec) - {"prior_sd"})
    if unknown:
        raise ValueError(f"{path}: [ground] takes prior_sd (m), not {unknown}")
    sd = float(spec.get("prior_sd", np.nan))
    if not (np.isfinite(sd) and sd > 0):
        raise ValueError(f"{path}: [ground] prior_sd must be a positive number of metres")
    return {"prior_sd": sd}


def _discrepancy(path, spec) -> dict:
    unknown = sorted(set(spec) - {"model", "eta", "count"})
    if unknown:
        raise ValueError(f"{path}: [discrepancy] takes model, eta and count, not {unknown}")
    out = {}
    if "model" in spec:
        if spec["model"] not in DISCREPANCY_MODELS:
            raise ValueError(
                f"{path}: [discrepancy] model {spec['model']!r} is not one of "
                f"{sorted(DISCREPANCY_MODELS)}"
            )
        out["model"] = spec["model"]
    if "eta" in spec:
        eta = float(spec["eta"])
        if not (np.isfinite(eta) and eta >= 0):
            raise ValueError(f"{path}: [discrepancy] eta must be a number ≥ 0")
        out["eta"] = eta
    if "count" in spec:
        count = spec["count"]
        if not (isinstance(count, int) and count >= 2):
            raise ValueError(f"{path}: [discrepancy] count must be an integer ≥ 2")
        out["count"] = count
    return out


#: Priors-file tables that set InversionSettings rather than a parameter's prior.
SETTINGS_TABLES = {"favd": _favd_range, "ground": _ground_prior, "discrepancy": _discrepancy}
