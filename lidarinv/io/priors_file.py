"""The priors file of an inversion (TOML): its reader.

Each table names a parameter of the inversion (:mod:`lidarinv.inference.model.parameters`)
and gives its prior, a fixed value, or ``free = true``; a few tables set inversion
settings instead, read by :mod:`lidarinv.inference.settings`.
"""

import tomllib

import numpy as np


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
    ``[discrepancy]``: :data:`lidarinv.inference.settings.SETTINGS_TABLES`) are left to
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
    from lidarinv.inference.model.parameters import COHORT2, LATENT, NUISANCE, STRUCTURE
    from lidarinv.inference.model.priors import make_prior
    from lidarinv.inference.settings import SETTINGS_TABLES

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
