"""Compact per-shot rows of ``studies/real_inversion.py`` for the validation pages: one
row a shot, small enough to publish with the summary, from which the page draws its
per-shot figure and table."""

import numpy as np

from lidarinv.inference.results.flags import flag_kind, warnings_among

#: The posterior quantities a row keeps (5/50/95 %), as ``real_inversion`` records them.
ROW_QUANTITIES = ("ground", "rh98", "rh98_footprint", "rh98_product", "canopy_height")


def flag_label(flag: str) -> str:
    """A flag's label for a table: its kind's words
    (:data:`lidarinv.inference.results.flags.FLAG_KINDS`: ``"misfit"``, ``"low
    acceptance"``, ``"not converged at the step cap"``), else its words before the first
    colon or parenthesis."""
    kind = flag_kind(flag)
    return kind if kind is not None else flag.split(":")[0].split(" (")[0].strip()


def warned(flags) -> bool:
    """Whether any of ``flags`` warns that the answer may be wrong
    (:func:`lidarinv.inference.results.flags.warnings_among`)."""
    return bool(warnings_among(flags))


def _rounded(value, digits=2):
    value = float(value)
    return round(value, digits) if np.isfinite(value) else None


def shot_rows(records) -> list:
    """One row per inverted shot: its number and flight line, the storeys chosen, whether
    it converged, its CPU time, the product's ground and RH98 (as published, and moved into
    the model's convention: ``real_inversion.convention_offset``), the posterior's 5/50/95 %
    of :data:`ROW_QUANTITIES` (m, to the cm), its flags' labels (:func:`flag_label`) and
    whether one of them is a warning (:func:`warned`).

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
                "product": {
                    k: _rounded(r.get("product", {}).get(k, np.nan))
                    for k in ("ground", "rh98", "rh98_model_convention")
                },
                "posterior": {
                    k: [_rounded(v) for v in posterior[k]] for k in ROW_QUANTITIES if k in posterior
                },
                "flags": sorted({flag_label(f) for f in r["flags"]}),
                "warned": warned(r["flags"]),
            }
        )
    return rows
