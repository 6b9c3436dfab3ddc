"""Compact per-shot rows of ``studies/real_inversion.py`` for the validation pages: one
row a shot, small enough to publish with the summary, from which the page draws its
per-shot figure and table."""

import numpy as np

#: The posterior quantities a row keeps (5/50/95 %), as ``real_inversion`` records them.
ROW_QUANTITIES = ("ground", "rh98", "rh98_footprint", "rh98_product", "canopy_height")
#: Flag kinds (:func:`flag_kind`, by their start) that tell a user not to take the answer
#: as it stands: the model misses part of the waveform, the canopy height contradicts the
#: footprint's own waveform, the ground may be another, or the run stopped at its cap. The
#: others say how the answer was reached (the instrument model's error raised, a few slow
#: walkers, the realisations' seed) and are on most LVIS shots.
WARNING_KINDS = (
    "misfit",
    "canopy height",
    "ground ambiguous",
    "ground may be hidden",
    "terrain outlier",
    "not converged",
)


def flag_kind(flag: str) -> str:
    """A flag's kind: its words before the first colon or parenthesis (``"misfit"``,
    ``"not converged at the step cap"``, ``"canopy height below the waveform's RH98"``)."""
    return flag.split(":")[0].split(" (")[0].strip()


def warned(flags) -> bool:
    """Whether any of ``flags`` is of a :data:`WARNING_KINDS` kind."""
    return any(flag_kind(f).startswith(WARNING_KINDS) for f in flags)


def _rounded(value, digits=2):
    value = float(value)
    return round(value, digits) if np.isfinite(value) else None


def shot_rows(records) -> list:
    """One row per inverted shot: its number and flight line, the storeys chosen, whether
    it converged, its CPU time, the product's ground and RH98, the posterior's 5/50/95 %
    of :data:`ROW_QUANTITIES` (m, to the cm), the kinds of its flags (:func:`flag_kind`)
    and whether one of them is a warning (:func:`warned`).

    Parameters
    ----------
    records : list of dict
        ``real_inversion`` shot records with a ``posterior`` (inverted shots).

    Returns
    -------
    list of dict
        JSON-ready; None for a value that is not finite.
    """
    rows = []
    for r in records:
        posterior = r["posterior"]
        rows.append(
            {
                "shot": str(r["shot"]),
                "lfid": r.get("lfid"),
                "cohorts": r.get("cohorts"),
                "converged": bool(r["converged"]),
                "cpu_seconds": _rounded(r.get("cpu_seconds", np.nan), 1),
                "product": {k: _rounded(r["product"][k]) for k in ("ground", "rh98")},
                "posterior": {
                    k: [_rounded(v) for v in posterior[k]] for k in ROW_QUANTITIES if k in posterior
                },
                "flags": sorted({flag_kind(f) for f in r["flags"]}),
                "warned": warned(r["flags"]),
            }
        )
    return rows
