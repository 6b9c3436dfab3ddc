"""The cohorts of trees the expected-waveform model integrates over, per parameter row.

Cohort 1 follows the vector's height distribution and crown mix; cohort 2, where the
model has one, its own distribution and the template's mix. Conditioning on the tallest
tree (:data:`.vectors.CONDITIONING_FIELDS`) stops every cohort at
``height_cap`` H, its trees below keeping their intensity λ·f(h) (so λ·F(H) stems on a
grid ending at H), and adds ``apex_density`` stems per hectare in cohort 1's mix, all of
height H: a point mass, whose optical depth is a closed form
(:func:`.depth.add_point_depth`).
"""

from collections.abc import Callable
from functools import partial
from typing import NamedTuple

import numpy as np

from .vectors import FIELD_INDEX as _I


class Cohort(NamedTuple):
    """One cohort's trees, per row: ``stems`` (stems/ha), ``pdf(h)`` their height
    density (1/m) at heights h (n, k) on the grid span [``lo``, ``hi``] (m), or None for
    trees all of height ``hi`` (a point mass), the crown shape ``fractions`` of the
    model's shapes ((n, S), or (1, S) for every row) and whether the row has the cohort
    at all (``present``, (n,) bool)."""

    stems: np.ndarray
    pdf: Callable | None
    lo: np.ndarray
    hi: np.ndarray
    fractions: np.ndarray
    present: np.ndarray


def _family_pdf(fast, args, h):
    return fast("pdf", h, *args)


def _height_columns(v, two_cohorts):
    """(weight, mean, sd) of cohort 1, then of cohort 2 if the model has one."""
    f2 = v[:, _I["cohort2_fraction"]]
    yield 1.0 - f2, v[:, _I["height_mean"]], v[:, _I["height_sd"]]
    if two_cohorts:
        safe = f2 > 0
        yield (
            f2,
            np.where(safe, v[:, _I["cohort2_height_mean"]], 1.0),
            np.where(safe, v[:, _I["cohort2_height_sd"]], 0.1),
        )


def cohorts(v, family, truncation, tail, mix_index, cohort2_fractions, two_cohorts):
    """The cohorts of full vectors ``v`` (n, len(VECTOR_FIELDS)).

    Parameters
    ----------
    family : forward.stand_params.HeightFamily
    truncation : float (sd units)
        Truncation of the ``truncnorm`` family.
    tail : float
        Probability left out at each end of a cohort's height grid.
    mix_index : array of int
        Columns of ``v`` holding cohort 1's fractions of the model's shapes.
    cohort2_fractions : array (1, S)
        Cohort 2's fractions of the model's shapes.
    two_cohorts : bool
        Whether the model has a cohort 2.

    Returns
    -------
    list of Cohort
        Cohort 1 and cohort 2 if the model has one (each stopped at ``height_cap``), and
        the apex trees at the cap where a row has any.
    """
    density, cap = v[:, _I["density"]], v[:, _I["height_cap"]]
    capped = np.isfinite(cap)
    mix = v[:, mix_index]
    out = []
    for cohort, (weight, mean, sd) in enumerate(_height_columns(v, two_cohorts)):
        shape_args, loc, scale = family.arguments(mean, sd, truncation)
        lo = family.fast("ppf", tail, shape_args, loc, scale)
        hi = np.maximum(family.fast("isf", tail, shape_args, loc, scale), lo + 1e-6)
        stems = density * weight
        if capped.any():  # the tallest stem stops every cohort
            below = 1.0 - family.fast("sf", np.where(capped, cap, hi), shape_args, loc, scale)
            stems = np.where(capped, stems * np.clip(below, 0.0, 1.0), stems)
            hi = np.where(capped, np.maximum(np.minimum(hi, cap), lo + 1e-6), hi)
        column = tuple(np.asarray(x, float)[..., None] for x in shape_args)
        args = (column, np.asarray(loc, float)[..., None], scale[:, None])
        pdf = partial(_family_pdf, family.fast, args)
        fractions = mix if cohort == 0 else cohort2_fractions
        out.append(Cohort(stems, pdf, lo, hi, fractions, weight > 0))
    apex = v[:, _I["apex_density"]]
    if np.any(apex > 0):  # physical rows with apex trees have a finite cap
        top = np.where(capped, cap, 1.0)
        out.append(Cohort(apex, None, top, top, mix, apex > 0))
    return out


def cohort_rows(cohort: Cohort, rows, n: int) -> Cohort:
    """The cohort of some of its ``n`` rows: exactly what :func:`cohorts` gives for them.

    Parameters
    ----------
    cohort : Cohort
    rows : array of bool (n,) or of int
    n : int
        The cohort's rows.

    Returns
    -------
    Cohort
    """

    def take(x):
        x = np.asarray(x)
        return x[rows] if x.ndim and x.shape[0] == n else x

    pdf = cohort.pdf
    if pdf is not None:
        fast, (column, loc, scale) = pdf.args
        pdf = partial(_family_pdf, fast, (tuple(take(c) for c in column), take(loc), take(scale)))
    return Cohort(
        take(cohort.stems), pdf, take(cohort.lo), take(cohort.hi), take(cohort.fractions),
        take(cohort.present),
    )  # fmt: skip


def narrowest_sd(v) -> np.ndarray:
    """The smallest height sd (m) of each row's cohorts, for full vectors ``v`` (n,)."""
    second = np.where(v[:, _I["cohort2_fraction"]] > 0, v[:, _I["cohort2_height_sd"]], np.inf)
    return np.minimum(v[:, _I["height_sd"]], second)
