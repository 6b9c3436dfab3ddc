"""The posterior of one shot: summary, diagnostics, and an HDF5 round trip."""

import json
from dataclasses import dataclass, field

import h5py
import numpy as np

import lidarinv

from .flags import is_warning, warnings_among
from .prior_learning import describe_prior_dominated, prior_dominated
from .realisation_spread import describe_spread, largest_spread

#: Reported quantiles (%) of every quantity.
QUANTILES = (5, 16, 50, 84, 95)
_LABELS = ("p05", "p16", "median", "p84", "p95")


@dataclass(eq=False)
class InversionResult:
    """Posterior samples and diagnostics of one shot.

    Attributes
    ----------
    shot_id : int or str
    parameter_names : tuple of str
        Free parameters, the columns of ``samples``: the sampled ones, then any
        marginalised one (the gain) drawn from its conditional posterior per sample.
    units : dict
        Units of every parameter and derived quantity.
    samples : array (m, ndim)
        Posterior samples in physical units, after burn-in and thinning.
    log_prob : array (m,)
    derived : dict of name → array (m,)
        Derived quantities per sample (RH of the model waveform, heights, volume, LAI...).
    fixed : dict
        Fixed parameters and their values.
    diagnostics : dict
        ``tau`` (steps) and ``ess`` per sampled coordinate (named in ``sampled``),
        ``acceptance``, ``n_steps``, ``n_walkers``, ``burn``, ``thin``, ``converged``,
        ``map_log_prob``; ``quantities``: per reported quantity the stopping rule
        monitored, ``ess_bulk``, ``ess_tail``, ``rhat`` (rank-normalised split R̂) and
        ``tau`` (steps) of the chain after burn-in
        (:func:`..sampling.stopping.quantity_diagnostics`); ``prior_learning``: per
        sampled parameter its posterior against its prior (contraction, KS distance,
        whether prior-dominated: :func:`.prior_learning.prior_learning`).
    flags : list of str
        What the run found to say: warnings (:attr:`warnings`: a misfit, non-convergence,
        ...) and notes (the instrument model's error raised, low acceptance, ...), each
        beginning with its kind's words (:data:`.flags.FLAG_KINDS`).
    profile_heights : array (m)
        Heights above ground of the crown-volume profile.
    profile : array (5, n_heights)
        Crown-volume profile quantiles (m³/m²/m), rows at :data:`QUANTILES`.
    axis, observed, censored : arrays
        The window of the observation (m, DN, bool).
    predictive : array (5, n_bins)
        Quantiles of the model mean b + a·W (DN), rows at :data:`QUANTILES`.
    noise_floor : float (DN)
        The detection threshold, noise mean + ``n_sigma`` σ, above which the signal's
        start and end are found.
    priors : list of dict
    settings : dict
    truth : dict
        Known true values for simulated shots.
    version : str
    replicated : array (5, n_bins) or None
        Quantiles of replicated observations (DN): the posterior predictive with the
        noise and the model discrepancy (the likelihood's ``replicate``); None
        in files written before it was stored.
    saturated : array of bool or None
        Window samples at the digitiser maximum (censored from above).
    floor, saturation : float (DN)
        The product's floor (censored samples sit at it) and digitiser maximum; NaN if
        none.
    """

    shot_id: object
    parameter_names: tuple
    units: dict
    samples: np.ndarray
    log_prob: np.ndarray
    derived: dict
    fixed: dict
    diagnostics: dict
    flags: list
    profile_heights: np.ndarray
    profile: np.ndarray
    axis: np.ndarray
    observed: np.ndarray
    censored: np.ndarray
    predictive: np.ndarray
    noise_floor: float
    priors: list
    settings: dict
    truth: dict = field(default_factory=dict)
    version: str = lidarinv.__version__
    replicated: np.ndarray | None = None
    saturated: np.ndarray | None = None
    floor: float = np.nan
    saturation: float = np.nan

    @property
    def converged(self) -> bool:
        return bool(self.diagnostics.get("converged", False))

    def column(self, name) -> np.ndarray:
        """Samples of a free parameter or a derived quantity.

        Parameters
        ----------
        name : str

        Returns
        -------
        array (m,)

        Raises
        ------
        KeyError
            Naming the quantities there are.
        """
        if name in self.parameter_names:
            return self.samples[:, self.parameter_names.index(name)]
        if name in self.derived:
            return self.derived[name]
        raise KeyError(f"no quantity {name!r}; have {self.quantity_names}")

    @property
    def prior_dominated(self) -> list:
        """The parameters whose posterior stayed at their prior (:mod:`.prior_learning`): their
        posterior quantiles describe the prior, not the stand."""
        return prior_dominated(self.diagnostics.get("prior_learning"))

    @property
    def warnings(self) -> list:
        """The flags that warn that the reported quantities may be wrong
        (:func:`.flags.is_warning`); a result without them is clean. The other flags say
        how the answer was reached."""
        return warnings_among(self.flags)

    @property
    def quantity_names(self) -> tuple:
        return tuple(self.parameter_names) + tuple(self.derived)

    def summary(self) -> dict:
        """Quantiles of every quantity.

        Returns
        -------
        dict
            ``{name: {"median", "p05", "p16", "p84", "p95", "units"}}``.
        """
        out = {}
        for name in self.quantity_names:
            values = self.column(name)
            values = values[np.isfinite(values)]
            q = np.percentile(values, QUANTILES) if values.size else np.full(5, np.nan)
            out[name] = {label: float(v) for label, v in zip(_LABELS, q)}
            out[name]["units"] = self.units.get(name, "")
        return out

    def footprint_canopy(self) -> dict | None:
        """The footprint's canopy: how likely it holds none, and its height if it holds one.

        Returns
        -------
        dict or None
            ``no_tree_probability``: the posterior mean of
            ``footprint_no_stem_probability``, P(no stem within the footprint's disc | y);
            ``bare_probability``: the posterior mean of ``footprint_bare``, P(the
            footprint's waveform shows nothing above a bare ground's return | y) (NaN where
            not drawn);
            ``none_probability``: P(the footprint holds no canopy its waveform sees | y), the
            share of samples whose footprint draws no stem or whose waveform shows no
            canopy return;
            ``height``: quantiles (as :meth:`summary`'s rows, m) of the footprint's canopy
            height as its waveform supports it: the tallest stem where the waveform shows
            a canopy, 0 where it shows none or no stem stands (:func:`seen_canopy_height`);
            ``height_given_canopy``: the same quantiles among the samples with a canopy
            (NaN where none has one). None for a result without these quantities.
        """
        if "footprint_no_stem_probability" not in self.derived:
            return None
        no_stem = self.derived["footprint_no_stem_probability"]
        height = seen_canopy_height(self.column("footprint_top_height"), self.derived)
        height = height[np.isfinite(height)]
        standing = height[height > 0.0]
        bare = self.derived.get("footprint_bare", np.array([np.nan]))
        bare = bare[np.isfinite(bare)]
        return {
            "no_tree_probability": float(np.mean(no_stem[np.isfinite(no_stem)])),
            "bare_probability": float(np.mean(bare)) if bare.size else float("nan"),
            "none_probability": float(1.0 - standing.size / height.size)
            if height.size
            else float("nan"),
            "height": _quantiles(height),
            "height_given_canopy": _quantiles(standing),
        }

    def summary_table(self) -> str:
        """A printable table: median and the 5/16/84/95 % quantiles, then the diagnostics.

        Returns
        -------
        str
        """
        header = (
            f"{'quantity':<20}{'units':>9}{'median':>11}{'5%':>11}{'16%':>11}{'84%':>11}{'95%':>11}"
        )
        lines = [f"shot {self.shot_id}", header, "-" * len(header)]
        for name, row in self.summary().items():
            numbers = "".join(f"{row[k]:>11.4g}" for k in ("median", "p05", "p16", "p84", "p95"))
            lines.append(f"{name:<20}{row['units']:>9}{numbers}")
        d = self.diagnostics
        tau = np.asarray(d["tau"], float)  # none where importance draws ended the run
        tau = "" if np.all(np.isnan(tau)) else f", max τ {np.max(tau):.0f}"
        lines.append(
            f"steps {d['n_steps']} × {d['n_walkers']} walkers{tau}, "
            f"acceptance {np.mean(d['acceptance']):.2f}, min ESS {np.min(d['ess']):.0f}, "
            f"{'converged' if self.converged else 'NOT CONVERGED'}"
        )
        if d.get("sampling") == "importance":
            i = d["importance"]
            lines.append(
                f"importance sampling: {i.get('made', i['draws'])} draws from a t fitted to the "
                f"chain at step {i['step']}, Pareto k̂ {i['khat']:.2f}, ESS {i['ess']:.0f}, "
                f"{i['draws']} kept (R̂ and τ: none)"
            )
        lines += _convergence_lines(d.get("quantities", {}))
        if "realisation_spread" in d:
            lines.append(describe_spread(d["realisation_spread"], d.get("realisations")))
        unconstrained = describe_prior_dominated(d.get("prior_learning"))
        if unconstrained:
            lines.append(unconstrained)
        if "seconds" in d:
            seconds = d["seconds"]
            start = f"start (MAP search) {seconds['start']:.1f} s"
            if "discrepancy" in seconds:  # the MAP search ran in the simulation stage
                start = (
                    f"MAP search and discrepancy simulation {seconds['discrepancy']:.1f} s, "
                    f"start {seconds['start']:.1f} s"
                )
            lines.append(f"time: {start}, sampling {seconds['sampling']:.1f} s")
        if "predictive_p_value" in d:
            lines.append(
                f"fit: DIC {d['dic']:.1f} ({d['effective_parameters']:.1f} effective "
                f"parameters), posterior-predictive p {d['predictive_p_value']:.3f}, "
                f"residuals {d.get('residual_scale', np.nan):.2f}× the modelled scatter"
            )
        if "model_error_needed" in d or "instrument_floor" in d:
            lines.append(_model_error_line(d))
        if "cohorts" in d:
            lines.append(_stand_model_line(d["cohorts"]))
        lines += [f"{'warning' if is_warning(f) else 'note'}: {f}" for f in self.flags]
        return "\n".join(lines)

    def summary_row(self) -> dict:
        """One flat row for batch tables.

        Returns
        -------
        dict
            Shot id, convergence, steps, largest τ, flags and every quantity's quantiles
            (str, float, int, bool values).
        """
        row = {
            "shot_id": str(self.shot_id),
            "converged": self.converged,
            "n_steps": int(self.diagnostics["n_steps"]),
            "max_tau": float(np.max(self.diagnostics["tau"])),
            "predictive_p_value": float(self.diagnostics.get("predictive_p_value", np.nan)),
            "residual_scale": float(self.diagnostics.get("residual_scale", np.nan)),
            **_convergence_extremes(self.diagnostics.get("quantities", {})),
            "max_realisation_spread": largest_spread(self.diagnostics),
            "cohorts": int((self.settings or {}).get("cohorts", 1)),
            "prior_dominated": "; ".join(self.prior_dominated),
            "flags": "; ".join(self.flags),
            "warned": bool(self.warnings),
        }
        canopy = self.footprint_canopy()
        if canopy is not None:
            row["footprint_no_tree_probability"] = canopy["no_tree_probability"]
            row["footprint_bare_probability"] = canopy["bare_probability"]
            row["footprint_no_canopy_probability"] = canopy["none_probability"]
            for key in ("height", "height_given_canopy"):
                row.update({f"footprint_{key}_{k}": canopy[key][k] for k in _LABELS})
        for name, stats in self.summary().items():
            row.update({f"{name}_{label}": stats[label] for label in _LABELS})
        return row

    # --- HDF5 -------------------------------------------------------------------------
    def write(self, group: h5py.Group):
        """Write into an open HDF5 group.

        Parameters
        ----------
        group : h5py.Group
        """
        group.attrs["shot_id"] = str(self.shot_id)
        group.attrs["shot_id_type"] = type(self.shot_id).__name__
        group.attrs["lidarinv_version"] = self.version
        group.attrs["parameter_names"] = json.dumps(list(self.parameter_names))
        for key in ("units", "fixed", "settings", "truth", "priors", "flags"):
            group.attrs[key] = json.dumps(_jsonable(getattr(self, key)))
        group.attrs["diagnostics"] = json.dumps(_jsonable(self.diagnostics))
        group.attrs["noise_floor"] = self.noise_floor
        group.attrs["quantiles"] = np.array(QUANTILES)
        group.create_dataset("samples", data=self.samples, compression="gzip")
        group.create_dataset("log_prob", data=self.log_prob, compression="gzip")
        derived = group.create_group("derived")
        for name, values in self.derived.items():
            derived.create_dataset(name, data=values, compression="gzip")
        for name in ("profile_heights", "profile", "axis", "observed", "predictive"):
            group.create_dataset(name, data=getattr(self, name))
        group.create_dataset("censored", data=self.censored.astype(np.uint8))
        if self.replicated is not None:
            group.create_dataset("replicated", data=self.replicated)
        if self.saturated is not None:
            group.create_dataset("saturated", data=self.saturated.astype(np.uint8))
        group.attrs["floor"], group.attrs["saturation"] = self.floor, self.saturation
        summary = group.create_group("summary")
        for name, stats in self.summary().items():
            summary.attrs[name] = json.dumps(stats)

    @classmethod
    def read(cls, group: h5py.Group) -> "InversionResult":
        """Read a result written by :meth:`write`.

        Parameters
        ----------
        group : h5py.Group

        Returns
        -------
        InversionResult
        """
        attrs = group.attrs
        shot_id = attrs["shot_id"]
        if attrs.get("shot_id_type") == "int":
            shot_id = int(shot_id)
        diagnostics = json.loads(attrs["diagnostics"])
        for key in ("tau", "acceptance", "ess"):
            diagnostics[key] = np.asarray(diagnostics[key], float)
        return cls(
            shot_id=shot_id,
            parameter_names=tuple(json.loads(attrs["parameter_names"])),
            units=json.loads(attrs["units"]),
            samples=group["samples"][()],
            log_prob=group["log_prob"][()],
            derived={name: group["derived"][name][()] for name in group["derived"]},
            fixed=json.loads(attrs["fixed"]),
            diagnostics=diagnostics,
            flags=json.loads(attrs["flags"]),
            profile_heights=group["profile_heights"][()],
            profile=group["profile"][()],
            axis=group["axis"][()],
            observed=group["observed"][()],
            censored=group["censored"][()].astype(bool),
            predictive=group["predictive"][()],
            noise_floor=float(attrs["noise_floor"]),
            priors=json.loads(attrs["priors"]),
            settings=json.loads(attrs["settings"]),
            truth=json.loads(attrs["truth"]),
            version=str(attrs["lidarinv_version"]),
            replicated=group["replicated"][()] if "replicated" in group else None,
            saturated=group["saturated"][()].astype(bool) if "saturated" in group else None,
            floor=float(attrs.get("floor", np.nan)),
            saturation=float(attrs.get("saturation", np.nan)),
        )

    def save(self, path, name="posterior", mode="a"):
        """Save to an HDF5 file under a group (replaced if present).

        Parameters
        ----------
        path : path
        name : str
        mode : str
            h5py file mode.
        """
        with h5py.File(path, mode) as handle:
            if name in handle:
                del handle[name]
            self.write(handle.create_group(name))

    @classmethod
    def load(cls, path, name="posterior") -> "InversionResult":
        """Read a result from an HDF5 file.

        Parameters
        ----------
        path : path
        name : str

        Returns
        -------
        InversionResult

        Raises
        ------
        ValueError
            Where the file has no such group.
        """
        with h5py.File(path, "r") as handle:
            if name not in handle:
                raise ValueError(f"{path}: no posterior group {name!r} (have {list(handle)})")
            return cls.read(handle[name])


def seen_canopy_height(top_height, derived) -> np.ndarray:
    """The footprint's canopy height as its waveform supports it, per sample.

    Parameters
    ----------
    top_height : array (n,) (m)
        The footprint's tallest stem per sample (0 where it draws none).
    derived : dict
        The result's derived quantities; ``footprint_bare`` (1 where the sample's footprint
        waveform shows nothing above a bare ground's return) where drawn.

    Returns
    -------
    array (n,) (m)
        The tallest stem, or 0 where the sample's waveform shows no canopy return: stems
        whose crowns return nothing the waveform can tell from the ground are no canopy
        it measures (a result without ``footprint_bare`` keeps the tallest stem).
    """
    top = np.asarray(top_height, float)
    bare = np.asarray(derived.get("footprint_bare", np.zeros(top.shape)), float)
    return np.where(bare == 1.0, 0.0, top)


def _quantiles(values) -> dict:
    """:data:`QUANTILES` of finite values, labelled as :meth:`InversionResult.summary`'s rows
    (NaN for none)."""
    q = np.percentile(values, QUANTILES) if np.size(values) else np.full(5, np.nan)
    return {label: float(v) for label, v in zip(_LABELS, q)}


def _convergence_lines(quantities) -> list:
    """The summary's lines on the reported quantities' bulk and tail ESS, R̂ and τ."""
    if not quantities:
        return []
    number = lambda v, form: "nan" if v is None else format(v, form)  # noqa: E731
    cells = [
        f"{name} {number(d['ess_bulk'], '.0f')}/{number(d['ess_tail'], '.0f')}/"
        f"{number(d['rhat'], '.3f')}/{number(d['tau'], '.0f')}"
        for name, d in quantities.items()
    ]
    lines = ["ESS bulk/tail, R̂, τ (steps) of the reported quantities: " + ", ".join(cells)]
    errors = [
        f"{name} {d['quantile_mcse']:.3f}"
        for name, d in quantities.items()
        if d.get("quantile_mcse") is not None and np.isfinite(d["quantile_mcse"])
    ]
    if errors:
        lines.append(
            "Monte Carlo error of the 5/50/95 % quantiles (posterior sd): " + ", ".join(errors)
        )
    return lines


def _convergence_extremes(quantities) -> dict:
    """The smallest bulk and tail ESS, the largest R̂ and the largest quantile Monte Carlo
    error (posterior sd) over the reported quantities."""

    def extreme(key, pick):  # over the quantities where it is known
        values = [d.get(key) for d in quantities.values()]
        known = [v for v in values if v is not None and np.isfinite(v)]
        return float(pick(known)) if known else np.nan

    return {
        "min_ess_bulk": extreme("ess_bulk", min),
        "min_ess_tail": extreme("ess_tail", min),
        "max_rhat": extreme("rhat", max),
        "max_quantile_mcse": extreme("quantile_mcse", max),
    }


def _stand_model_line(choice) -> str:
    """The summary's line on the stand model :func:`..passes.cohorts.choose_cohorts` chose."""
    if len(choice["bic"]) == 1 and "canopy_extent_m" in choice:  # two storeys not searched
        extent, width = choice["canopy_extent_m"], choice["pulse_width_m"]
        return (
            f"stand model: {choice['chosen']} cohort: the canopy return spans {extent:.1f} m, "
            f"{extent / width:.1f} pulse widths of {width:.1f} m, too short for two storeys"
        )
    bic = ", ".join(f"{k} cohort(s) {v:.1f}" for k, v in choice["bic"].items())
    return f"stand model: {choice['chosen']} cohort(s), by BIC ({bic})"


def _model_error_line(d) -> str:
    """The summary's line on the instrument model's error: used, needed and its ceiling."""
    needed = d.get("model_error_needed")
    finite = needed is not None and np.isfinite(needed)
    needed = f"{100 * needed:.0f} %" if finite else "more than any"
    return (
        f"model error: {100 * (d.get('instrument_floor') or 0.0):.0f} % of the signal per bin "
        f"(the residuals need {needed}; ceiling {100 * d.get('model_error_ceiling', np.nan):.0f} %)"
    )


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_jsonable(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value
