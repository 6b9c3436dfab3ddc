"""The parameter space of an inversion: priors, fixed values and sampling coordinates.

A :class:`ParameterSpace` is an ordered set of :class:`Parameter`; the free ones form the
sampled vector, in physical units x or in the unbounded coordinates u the sampler moves
in (each bounded prior mapped to the real line, :mod:`.priors`, and the posterior's
ridges straightened, :mod:`.coordinates`). The default parameterisation is in
:mod:`.parameters`.
"""

from dataclasses import dataclass, replace

import numpy as np

from forward.backends import resolve

from . import coordinates, top_coordinates
from .prior_table import DEFAULT_UNBOUNDED, PriorTable
from .stand import TOP_SDS
from .tallest_stem import NO_STEM_DEPTH_M, TALLEST_STEM


@dataclass(frozen=True)
class Parameter:
    """One inversion parameter.

    Parameters
    ----------
    name : str
    units : str
    prior : Uniform, LogUniform or TruncatedNormal
    fixed : float or None
        If set, the parameter is held at this value and not sampled.
    description : str
    marginalised : bool
        Integrated out of the likelihood against its prior (:mod:`..likelihood.marginal`, the gain
        only) instead of sampled; its posterior samples are drawn afterwards.
    """

    name: str
    units: str
    prior: object
    fixed: float | None = None
    description: str = ""
    marginalised: bool = False

    @property
    def free(self) -> bool:
        """Sampled: neither fixed nor marginalised."""
        return self.fixed is None and not self.marginalised


#: Cover within this of 1 is left out of the joint cover-PAI coordinates' range (a prior
#: reaching cover 1 would leave the ridge unbounded; the mass left out is ~1e-9).
COVER_MARGIN = 1e-9


def _support(parameter, upper=np.inf) -> tuple:
    """[lower, min(upper, the prior's upper)] of a parameter's prior."""
    form = parameter.prior.form()
    return float(form.lower), float(min(form.upper, upper))


class ParameterSpace:
    """An ordered set of :class:`Parameter`; the free ones form the sampled vector.

    Parameters
    ----------
    parameters : iterable of Parameter
    ridges : tuple of str
        Ridge-straightening coordinates of :mod:`.coordinates` to sample in, from
        :data:`.coordinates.RIDGE_COORDINATES`; each applies when its parameters are free
        (the posterior is unchanged; only its sampling coordinates):

        - ``cover-pai``: cover and PAI jointly, when both are free;
        - ``crown-base``: the log crown-base height of the mean tree instead of
          ``crown_length_ratio``, when that is free and ``top_height`` and ``height_sd``
          are in the space (free or fixed).
        - ``ground-centroid``: the centroid of the ground-plus-understory return instead
          of ``ground_elevation``, when that is free and the understory is in the space
          with a non-zero LAI (free or fixed).
        - ``mean-height``: the mean tree height instead of ``top_height``, when both it and
          ``height_sd`` are free, the top's prior is bounded above, and the tallest stem's
          gap does not already take the top.
        - ``tallest-stem``: the log gap between the top height and the tallest stem
          instead of ``top_height``, when both are free.
        - ``lower-storey-top``: the lower storey's log top height above its prior's floor
          instead of ``cohort2_top_ratio``, when that is free and ``top_height`` is in the
          space (free or fixed).
    unbounded : str
        Map of each bounded prior to the real line, from :data:`.prior_table.UNBOUNDED_MAPS`.
    interception_slope : float
        a = k·G·Ω of the shot's instrument (``Instrument.extinction_per_favd``), the
        slope of the cover–PAI and ground-centroid coordinates.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` for the ridge maps
        (:func:`.coordinates.ridges_from_unbounded`).
    """

    def __init__(
        self,
        parameters,
        ridges=coordinates.DEFAULT_RIDGES,
        unbounded=DEFAULT_UNBOUNDED,
        interception_slope=coordinates.INTERCEPTION_SLOPE,
        backend="auto",
    ):
        self.parameters = tuple(parameters)
        self.ridges = tuple(ridges)
        self.unbounded = unbounded
        self.interception_slope = float(interception_slope)
        self.backend = resolve(backend)
        unknown = sorted(set(self.ridges) - set(coordinates.RIDGE_COORDINATES))
        if unknown:
            raise ValueError(
                f"unknown sampling coordinates {unknown}; known: "
                f"{list(coordinates.RIDGE_COORDINATES)}"
            )
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate parameter names in {names}")
        self.by_name = {p.name: p for p in self.parameters}
        self.free = tuple(p for p in self.parameters if p.free)
        self.names = tuple(p.name for p in self.free)
        if not self.free:
            raise ValueError("every parameter is fixed; nothing to infer")
        self._priors = PriorTable([p.prior for p in self.free], unbounded)
        both = "cover" in self.names and "pai" in self.names
        self._joint = (
            (
                self.names.index("cover"),
                self.names.index("pai"),
                _support(self.by_name["cover"], upper=1.0 - COVER_MARGIN),
                _support(self.by_name["pai"]),
            )
            if both and "cover-pai" in self.ridges
            else None
        )
        needed = ("crown_length_ratio", "top_height", "height_sd")
        self._base = (
            (
                self.names.index("crown_length_ratio"),
                *_support(self.by_name["crown_length_ratio"], upper=1.0),
            )
            if "crown-base" in self.ridges
            and "crown_length_ratio" in self.names
            and set(needed) <= set(names)
            else None
        )
        self._storey = self._storey_map() if "lower-storey-top" in self.ridges else None
        self._centroid = self._centroid_map() if "ground-centroid" in self.ridges else None
        stem = ("top_height", TALLEST_STEM)
        self._stem = (
            tuple(self.names.index(n) for n in stem)
            if "tallest-stem" in self.ridges and set(stem) <= set(self.names)
            else None
        )
        self._mean_height = self._mean_height_map() if "mean-height" in self.ridges else None
        self._sd_cap = self._sd_cap_map()
        inputs = ("top_height", "height_sd", "understory_lai", "understory_height", "rho_ratio")
        self._ridge_inputs = (  # for the compiled maps: each a column, or FIXED and a value
            np.array([self._index(n) for n in inputs], np.int64),
            np.array([self._fixed_value(n) for n in inputs], float),
        )

    @property
    def ndim(self) -> int:
        return len(self.free)

    def signature(self) -> str:
        """The sampled coordinates, for labelling stored chains.

        Returns
        -------
        str
            The unbounded map, the ridge coordinates, each free parameter's prior and the
            marginalised parameters.
        """
        joint = "cover-pai-joint-v2" if self._joint is not None else "per-parameter"
        if self._base is not None:
            joint += ", crown-base-v2"
        if self._sd_cap is not None:
            joint += ", height-sd-capped-v1"
        if self._centroid is not None:
            joint += ", ground-centroid-v1"
        if self._stem is not None:
            joint += ", tallest-stem-gap-v1"
        if self._mean_height is not None:
            joint += f", mean-height-v1(p={self._mean_height[3]:g})"
        if self._storey is not None:
            joint += f", lower-storey-top-v1(p={self._storey[3]:g})"
        priors = ";".join(f"{p.name}:{p.prior.describe()}" for p in self.free)
        marginalised = "".join(f"; marginalised {name}" for name in self.marginalised)
        return f"lidarinv {self.unbounded} transforms, {joint}; {priors}{marginalised}"

    @property
    def marginalised(self) -> tuple:
        """Names of the parameters integrated out of the likelihood."""
        return tuple(p.name for p in self.parameters if p.marginalised)

    def units(self, name) -> str:
        """The units of a parameter.

        Parameters
        ----------
        name : str

        Returns
        -------
        str
        """
        return self.by_name[name].units

    def values(self, x) -> dict:
        """Every parameter's values for rows of the free ones.

        Parameters
        ----------
        x : array (n, ndim)
            Physical values of the free parameters.

        Returns
        -------
        dict
            Name → (n,) values: the free ones from the columns of x, the fixed ones filled;
            marginalised ones are absent.
        """
        x = np.atleast_2d(np.asarray(x, float))
        out = {p.name: x[:, i] for i, p in enumerate(self.free)}
        for p in self.parameters:
            if p.fixed is not None:
                out[p.name] = np.full(x.shape[0], float(p.fixed))
        return out

    def log_prior(self, x) -> np.ndarray:
        """The free parameters' log prior density.

        Parameters
        ----------
        x : array (n, ndim)

        Returns
        -------
        array (n,)
            Σ log π_k(x_k); −inf outside the support.
        """
        x = np.atleast_2d(np.asarray(x, float))
        total = self._priors.log_pdf(x).sum(axis=1)
        return np.where(np.isfinite(total), total, -np.inf)

    def from_unbounded(self, u, backend=None):
        """Physical values and log|Jacobian| from unbounded coordinates.

        Parameters
        ----------
        u : array (n, ndim)
        backend : str, optional
            For the ridge maps (:func:`.coordinates.ridges_from_unbounded`); the space's own
            by default.

        Returns
        -------
        x : array (n, ndim)
        log_jac : array (n,)
            log|∂x/∂u|: the priors' maps, the tallest stem's gap, then the ridge maps.
        """
        u = np.atleast_2d(np.asarray(u, float))
        x, log_jac = self._priors.from_unbounded(u)
        if self._stem is not None:  # before the crown base, which needs the top
            top, stem = self._stem
            x[:, top], log_jac[:, top] = top_coordinates.top_from_stem_gap(x[:, stem], u[:, top])
        if self._sd_cap is not None:  # after the top, before the crown base
            sd, *form = self._sd_cap
            x[:, sd], extra = top_coordinates.height_sd_capped(
                x[:, sd], self._sd_cap_top(x), *form, TOP_SDS
            )
            log_jac[:, sd] += extra
        if self._mean_height is not None:  # after the sd it needs
            top, sd, top_upper, power = self._mean_height
            x[:, top], log_jac[:, top] = top_coordinates.top_from_mean_height(
                u[:, top], x[:, sd], top_upper, TOP_SDS, power
            )
        coordinates.ridges_from_unbounded(
            u, x, log_jac, self._joint, self._base, self._centroid, self._ridge_inputs,
            TOP_SDS, self.interception_slope, storey=self._storey,
            backend=self.backend if backend is None else backend,
        )  # fmt: skip
        return x, log_jac.sum(axis=1)

    def to_unbounded(self, x):
        """Unbounded coordinates of physical values: the inverse of :meth:`from_unbounded`.

        Parameters
        ----------
        x : array (n, ndim)

        Returns
        -------
        array (n, ndim)
            NaN or ±inf where x lies outside the support.
        """
        x = np.atleast_2d(np.asarray(x, float))
        mapped = x.copy()  # the values the priors' own maps give
        if self._centroid is not None:
            g, lower, stretch = self._centroid
            centroid = x[:, g] + self._understory_centroid(x)
            mapped[:, g] = lower + (centroid - lower) / stretch
        if self._sd_cap is not None:
            sd, *form = self._sd_cap
            mapped[:, sd] = top_coordinates.height_sd_uncapped(
                x[:, sd], self._sd_cap_top(x), *form, TOP_SDS
            )
        u = self._priors.to_unbounded(mapped)
        if self._mean_height is not None:
            top, sd, top_upper, power = self._mean_height
            u[:, top] = top_coordinates.mean_height_from_top(
                x[:, top], x[:, sd], top_upper, TOP_SDS, power
            )
        if self._joint is not None:
            c, a, cover_bounds, pai_bounds = self._joint
            u[:, c], u[:, a] = coordinates.from_cover_pai_bounded(
                x[:, c], x[:, a], cover_bounds, pai_bounds, self.interception_slope
            )
        if self._base is not None:
            r, *bounds = self._base
            u[:, r] = coordinates.crown_base_from_ratio(x[:, r], self._mean(x), bounds)
        if self._storey is not None:
            k, *bounds, power = self._storey
            top = self._column(x, "top_height")
            u[:, k] = coordinates.lower_top_from_ratio(x[:, k], top, bounds, power)
        if self._stem is not None:
            top, stem = self._stem
            u[:, top] = top_coordinates.stem_gap_from_top(x[:, top], x[:, stem])
        return u

    def _index(self, name) -> int:
        return self.names.index(name) if name in self.names else coordinates.FIXED

    def _fixed_value(self, name) -> float:
        p = self.by_name.get(name)
        return np.nan if p is None or p.fixed is None else float(p.fixed)

    def _column(self, x, name):
        """Values of parameter ``name`` in rows x, free or fixed."""
        return x[:, self.names.index(name)] if name in self.names else self.by_name[name].fixed

    def _mean(self, x):
        """Mean tree height (m) of rows x: top − TOP_SDS·sd, free or fixed."""
        return self._column(x, "top_height") - TOP_SDS * self._column(x, "height_sd")

    def _understory_centroid(self, x):
        """Height (m) of the ground-plus-understory centroid above the ground, rows x."""
        lai, height, ratio = (
            self._column(x, name) for name in ("understory_lai", "understory_height", "rho_ratio")
        )
        return coordinates.understory_centroid(lai, height, ratio, self.interception_slope)

    def _sd_cap_map(self):
        """(column, w₀, w₁, log scale) of the height sd's capped map
        (:func:`.top_coordinates.height_sd_capped`), or None where sd is not free."""
        if "height_sd" not in self.names or "top_height" not in self.by_name:
            return None
        form = self.by_name["height_sd"].prior.form()
        return self.names.index("height_sd"), form.w_lower, form.w_upper, form.log_scale

    def _sd_cap_top(self, x):
        """The top whose mean height caps the sd's map (:meth:`_sd_cap_map`): each row's,
        or under the mean-height coordinate (where the top follows from the sd) the upper
        end of the top's prior."""
        return self._column(x, "top_height") if self._mean_height is None else self._mean_height[2]

    def _mean_height_map(self):
        """(top column, sd column, top₁, p) of the mean-height coordinate
        (:func:`.top_coordinates.top_from_mean_height`), or None where it does not apply."""
        if not {"top_height", "height_sd"} <= set(self.names) or self._stem is not None:
            return None
        top_upper = float(self.by_name["top_height"].prior.form().upper)
        if not np.isfinite(top_upper):
            return None
        top, sd = self.names.index("top_height"), self.names.index("height_sd")
        return top, sd, top_upper, coordinates.LOWER_TOP_WALL_POWER

    def _storey_map(self):
        """(column, ρ₀, ρ₁, p) of the lower storey's top coordinate
        (:func:`.coordinates.ratio_from_lower_top`), or None where it does not apply."""
        if "cohort2_top_ratio" not in self.names or "top_height" not in self.by_name:
            return None
        lower, upper = _support(self.by_name["cohort2_top_ratio"], upper=1.0)
        column = self.names.index("cohort2_top_ratio")
        return column, max(lower, 0.0), upper, coordinates.LOWER_TOP_WALL_POWER

    def _centroid_map(self):
        """(column, lower, stretch) of the ground-centroid coordinate, or None where it does
        not apply: the ground prior's range [lower, upper] widened to upper + the tallest
        understory, so that c = zg + f(…) covers it (f ≤ hu)."""
        needed = ("understory_lai", "understory_height", "rho_ratio")
        if "ground_elevation" not in self.names or not set(needed) <= set(self.by_name):
            return None
        lai = self.by_name["understory_lai"]
        if lai.fixed is not None and lai.fixed <= 0:
            return None
        height = self.by_name["understory_height"]
        tallest = height.fixed if height.fixed is not None else height.prior.form().upper
        ground = self.by_name["ground_elevation"].prior.form()
        if ground.log_scale or not np.isfinite(ground.upper - ground.lower + tallest):
            return None
        span = ground.upper - ground.lower
        return self.names.index("ground_elevation"), ground.lower, (span + tallest) / span

    def sample_prior(self, rng, size) -> np.ndarray:
        """Draws from the free parameters' priors (candidates for the MAP search).

        Parameters
        ----------
        rng : numpy.random.Generator
        size : int

        Returns
        -------
        array (size, ndim)
            A tallest stem sampled with the top height is drawn uniformly over the stand's
            height range below it and the no-stem range under that (its law given the stand
            needs the stand's density: these are candidates, to be scored).
        """
        x = np.column_stack([p.prior.sample(rng, size) for p in self.free])
        if TALLEST_STEM in self.names and "top_height" in self.by_name:
            top = self._column(x, "top_height")
            span = np.minimum(2.0 * TOP_SDS * self._column(x, "height_sd"), top)
            span += NO_STEM_DEPTH_M  # and the no-stem range below the lowest tree
            x[:, self.names.index(TALLEST_STEM)] = top - span * rng.uniform(size=size)
        return x

    def with_changes(self, changes: dict) -> "ParameterSpace":
        """A copy with per-parameter changes.

        Parameters
        ----------
        changes : dict
            ``{name: {"prior": …, "fixed": …, "marginalised": …}}``.

        Returns
        -------
        ParameterSpace

        Raises
        ------
        ValueError
            Naming unknown parameters.
        """
        unknown = sorted(set(changes) - set(self.by_name))
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown}; known: {sorted(self.by_name)}")
        out = []
        for p in self.parameters:
            change = changes.get(p.name, {})
            out.append(replace(p, **change) if change else p)
        return ParameterSpace(
            out, self.ridges, self.unbounded, self.interception_slope, self.backend
        )

    def describe(self) -> list:
        """Every parameter's name, units, fixed value, prior and description.

        Returns
        -------
        list of dict
        """
        return [
            {
                "name": p.name,
                "units": p.units,
                "fixed": p.fixed,
                "marginalised": p.marginalised,
                "prior": p.prior.describe(),
                "description": p.description,
            }
            for p in self.parameters
        ]
