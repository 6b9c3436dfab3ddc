"""From inversion parameters to the expected-waveform model, and the derived quantities.

Cover c and crown plant area index L fix stem density and FAVD through the Poisson-stand
identities of :mod:`forward.poisson_stand` (for a height density f and crown radius
R(h) = r0 + r1·h; the expectations are closed forms in the raw moments E[h^k] of the
height family):

    c = 1 − exp(−λ·E[π R²])             →  λ = −ln(1 − c) / E[π R²]   (stems/m²)
    L = λ·FAVD·Σ_s m_s κ_s v_s E[π R² ℓ h]  →  FAVD = L / (λ·Σ …)     (m²/m³)

with m_s the shape fractions, κ_s the per-shape FAVD ratios, v_s the volume fractions of
the shapes and ℓ the crown length ratio. The top height is mean + 2·sd of the height
family: for the default truncated normal (truncated at ±2 sd) it is the tallest tree.
The crown-volume profile, whose integrand has kinks at the crown ends, uses Gauss–Legendre
quadrature on the bulk of each row's distribution.

:func:`.stand_columns.stand_columns` takes ``backend=`` (:mod:`forward.backends`): its
compiled kernel (truncated-normal heights) computes in two passes over the rows what numpy
computes in some forty calls on short arrays, calling the same identities. The model
vector is built
by field name (:func:`forward.expected.vectors_by_name`): an inversion parameter named
as a vector field passes through; the others come from the template.
"""

import numpy as np

from forward import poisson_stand
from forward.backends import resolve
from forward.crowns import CROWN_SHAPES
from forward.expected import CONDITIONING_FIELDS, MIX_FIELDS, VECTOR_FIELDS, vectors_by_name
from forward.height_families import HEIGHT_DISTRIBUTIONS
from forward.stand_params import StandParams

from . import tallest_stem
from .stand_columns import DOMINANT_PER_HA, stand_columns
from .tallest_stem import TALLEST_STEM, TALLEST_STEM_POSITION

#: top_height = height_mean + TOP_SDS·height_sd.
TOP_SDS = 2.0

#: Expected-model vector fields the mapping fills, in order (single cohort, no mix, the
#: whole stand rather than one conditioned on its tallest tree).
MODEL_FIELDS = tuple(
    f
    for f in VECTOR_FIELDS
    if not f.startswith(("cohort2_", "mix_")) and f not in CONDITIONING_FIELDS
)

#: Scalar derived quantities reported per sample (units).
DERIVED = {
    "density": "stems/ha",
    "favd": "m2/m3",
    "mean_height": "m",
    "dominant_height": "m",
    "crown_volume": "m3/ha",
    "lai": "m2/m2",
}


def default_template(shape_pair=("cone", "ellipsoid")) -> StandParams:
    """Template stand of the default parameterisation.

    Parameters
    ----------
    shape_pair : (str, str)
        The crown shapes mixed by ``cone_fraction``.

    Returns
    -------
    StandParams
        Truncated-normal heights truncated at ±:data:`TOP_SDS` sd, one cohort, the two
        shapes half and half; the values the parameters do not set (crown-radius
        intercept, FAVD ratios) are the template's.
    """
    return StandParams(
        density=500.0,
        height_mean=15.0,
        height_sd=3.0,
        height_family="truncnorm",
        height_truncation=TOP_SDS,
        shape_mix={shape_pair[0]: 0.5, shape_pair[1]: 0.5},
    )


def _unit_rule(nodes):
    """Gauss–Legendre nodes and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    return 0.5 * (x + 1.0), 0.5 * w


class StandMapping:
    """Vectorised map from inversion parameters to expected-model vectors.

    Parameters
    ----------
    template : StandParams
        Height family, truncation, FAVD ratios and crown-radius intercept (single cohort).
    shape_pair : (str, str)
        Shapes mixed by ``cone_fraction``: the first gets ``cone_fraction``, the second
        the rest.
    profile_nodes : int
        Nodes of the crown-volume profile, whose integrand has kinks at the crown ends.
    footprint_sigma_m : float (m) or None
        If set, condition each footprint on its tallest stem within the disc of radius
        R = :data:`.tallest_stem.TALLEST_STEM_RADIUS_SIGMAS`·σf (area A): the parameters
        then include the latents :data:`.tallest_stem.TALLEST_STEM_LATENTS`: the stem's
        height H (m), whose law given the stand is that of the tallest of a Poisson(λA)
        draw of stems (:func:`.tallest_stem.mixture_log_density`), and V, uniform a priori: the
        stem stands at r² = V·R² from the centre. Cohort 1 stops at H (``height_cap``) and
        the stem itself is an apex cohort whose density is its footprint weight
        (``apex_density``, :func:`.tallest_stem.stem_density_per_ha`). Stems outside the
        disc are capped too, an approximation worth e⁻² of the weight.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` for :func:`.stand_columns.stand_columns`
        (compiled for truncated-normal heights only).
    """

    def __init__(
        self,
        template: StandParams,
        shape_pair=("cone", "ellipsoid"),
        profile_nodes=48,
        footprint_sigma_m=None,
        backend="auto",
    ):
        if template.cohort2_fraction > 0:
            raise ValueError("the default parameterisation models a single cohort")
        unknown = [s for s in shape_pair if s not in CROWN_SHAPES]
        if unknown or len(shape_pair) != 2 or shape_pair[0] == shape_pair[1]:
            raise ValueError(f"shape_pair needs two different shapes of {list(CROWN_SHAPES)}")
        self.template = template
        self.shape_pair = tuple(shape_pair)
        self.family = HEIGHT_DISTRIBUTIONS[template.height_family]
        self.truncation = template.height_truncation
        self._profile_rule = _unit_rule(profile_nodes)
        ratio = dict(zip(CROWN_SHAPES, template.favd_ratio))
        self._volume = np.array([CROWN_SHAPES[s].volume_fraction for s in shape_pair])
        self._leaf = self._volume * np.array([ratio[s] for s in shape_pair])
        self.model_free = MODEL_FIELDS + tuple(f"mix_{s}" for s in shape_pair)
        assert all(f in MIX_FIELDS for f in self.model_free[len(MODEL_FIELDS) :])
        #: the backend of the stand columns: compiled for truncated-normal heights
        compiled = resolve(backend) == "numba" and template.height_family == "truncnorm"
        self.backend = "numba" if compiled else "numpy"
        #: whether footprints are conditioned on their tallest stem (and its disc's area)
        self.conditioned = footprint_sigma_m is not None
        if self.conditioned:
            if not (np.isfinite(footprint_sigma_m) and footprint_sigma_m > 0):
                raise ValueError(f"footprint_sigma_m must be positive, got {footprint_sigma_m}")
            self.footprint_sigma_m = float(footprint_sigma_m)
            self.tallest_stem_area = tallest_stem.disc_area(footprint_sigma_m)
            self.model_free += tuple(CONDITIONING_FIELDS)

    def _value(self, v, name):
        """The parameter ``name`` of rows ``v`` where they have it, else the template's."""
        return v[name] if name in v else getattr(self.template, name)

    def _quadrature(self, mean, sd):
        """Heights (n, q) and weights (n, q) of the profile's rule over the bulk of each
        row's height distribution (all but 1e-9 in each tail)."""
        x, w = self._profile_rule
        t = self.truncation
        low = self.family.ppf(1e-9, mean, sd, t)
        high = self.family.isf(1e-9, mean, sd, t)
        low = np.minimum(low, high)
        h = low[:, None] + (high - low)[:, None] * x
        weight = (high - low)[:, None] * w * self.family.pdf(h, mean[:, None], sd[:, None], t)
        return h, weight

    def _moments(self, mean, sd, v):
        """Heights (n, q), their probabilities (n, q) and crown areas (n, q) (m²) of the
        profile's rule over each row's height distribution (mean, sd)."""
        h, weight = self._quadrature(mean, sd)
        total = weight.sum(axis=1)
        p = weight / np.where(total > 0, total, 1.0)[:, None]
        r0 = np.asarray(self._value(v, "crown_radius_intercept"), float)
        radius = (r0[..., None] if r0.ndim else r0) + v["crown_radius_slope"][:, None] * h
        return h, p, np.pi * radius**2

    def shape_profile(self, mean, sd, mix, v, z) -> np.ndarray:
        """Mean crown volume per stem and unit height of trees of one height law (m³/m).

        Parameters
        ----------
        mean, sd : array (n,) (m)
            The height family's mean and sd per row.
        mix : array (n, 2) or (2,)
            Fractions of the shape pair.
        v : dict
            The parameters' (n,) values (crown length ratio and radius law).
        z : array (nz,) (m)
            Heights above the ground.

        Returns
        -------
        array (n, nz) (m³/m)
            Σ_s m_s ∫ f(h)·π Rc(h)²·a_s((z − (1 − ℓ)h)/ℓh) dh (a_s the shape's section).
        """
        h, p, area = self._moments(mean, sd, v)
        length = v["crown_length_ratio"][:, None, None] * h[:, None, :]
        s = (z[None, :, None] - (h[:, None, :] - length)) / length
        mix = np.broadcast_to(mix, (mean.size, 2))
        out = np.zeros((mean.size, z.size))
        for k, shape in enumerate(self.shape_pair):
            section = CROWN_SHAPES[shape].section(s)
            out += mix[:, k, None] * np.sum((p * area)[:, None, :] * section, axis=2)
        return out

    def valid(self, v) -> np.ndarray:
        """Rows whose parameters describe a stand (before any model evaluation).

        Parameters
        ----------
        v : dict
            Every parameter's (n,) values.

        Returns
        -------
        array of bool (n,)
            A positive mean height and sd the family supports, cover in (0, 1), positive PAI,
            crown length ratio in (0, 1], cone fraction in [0, 1], a positive understory
            height, non-negative understory LAI and ρv/ρg, a positive crown-radius slope.
        """
        mean, sd = v["top_height"] - TOP_SDS * v["height_sd"], v["height_sd"]
        ok = (mean > 0) & (sd > 0) & (v["cover"] > 0) & (v["cover"] < 1) & (v["pai"] > 0)
        ok &= (v["crown_length_ratio"] > 0) & (v["crown_length_ratio"] <= 1)
        ok &= (v["cone_fraction"] >= 0) & (v["cone_fraction"] <= 1)
        ok &= (v["understory_height"] > 0) & (v["understory_lai"] >= 0)
        ok &= (v["rho_ratio"] >= 0) & (v["crown_radius_slope"] > 0)
        safe_mean, safe_sd = np.where(ok, mean, 1.0), np.where(ok, sd, 0.1)
        return ok & self.family.valid(safe_mean, safe_sd, self.truncation)

    def model_vectors(self, v):
        """Expected-model vectors and scalar derived quantities of parameter rows.

        Parameters
        ----------
        v : dict
            Every parameter's (n,) values (:meth:`.space.ParameterSpace.values`); rows
            must be :meth:`valid`.

        Returns
        -------
        vectors : array (n, len(model_free))
            The fields of :attr:`model_free`, built by name: parameters named as vector
            fields pass through; density, mean height, FAVD, the reflectances, the shape
            mix (and the tallest stem's cap and apex density) are mapped; the rest is the
            template's.
        derived : dict
            Crown area (m²), density (stems/ha), FAVD (m²/m³), mean and dominant height
            (m), crown volume (m³/ha) and LAI (m²/m²) per row; with the tallest stem, its
            height (0 where the disc holds none) and log density (1/m).
        """
        columns = stand_columns(
            v, self._value(v, "crown_radius_intercept"), TOP_SDS, self.family,
            self.truncation, self._volume, self._leaf, DOMINANT_PER_HA, backend=self.backend,
        )  # fmt: skip
        lam, mean, favd, area, m1, volume, dominant = columns.T
        fields = self.stand_fields(v, lam, mean, favd)
        if self.conditioned:
            args, lowest = tallest_stem.arguments_and_lowest(
                self.family, mean, v["height_sd"], self.truncation
            )
            stem = tallest_stem.condition(
                self.family, [(1.0, args)], lowest, lam * self.tallest_stem_area,
                v[TALLEST_STEM], v[TALLEST_STEM_POSITION], self.footprint_sigma_m,
            )  # fmt: skip
            fields.update(stem.pop("fields"))
        vectors = vectors_by_name(fields, self.model_free)
        derived = {
            "crown_area": area,  # m², not a blob: for the discrepancy model
            "density": lam * 1e4,
            "favd": favd,
            "mean_height": m1,
            "dominant_height": dominant,
            "crown_volume": volume * 1e4,
            "lai": v["pai"] + v["understory_lai"],
        }
        if self.conditioned:  # the stem's height (m, 0 where none) and log density
            derived.update(stem)
        return vectors, derived

    def stand_fields(self, v, density_m2, height_mean, favd) -> dict:
        """The model-vector fields of rows: the parameters named as fields, and the
        stand's density (stems/ha), cohort 1's height mean (m), FAVD (m²/m³), crown-radius
        intercept, reflectances (ρg = 1) and shape mix."""
        cone = v["cone_fraction"]
        fields = {name: v[name] for name in self.model_free if name in v}
        fields.update(
            {
                "density": density_m2 * 1e4,
                "height_mean": height_mean,
                "crown_radius_intercept": self._value(v, "crown_radius_intercept"),
                "favd": favd,
                "canopy_reflectance": v["rho_ratio"],
                "ground_reflectance": 1.0,
                f"mix_{self.shape_pair[0]}": cone,
                f"mix_{self.shape_pair[1]}": 1.0 - cone,
            }
        )
        return fields

    def crowns_spanning(self, v, z) -> np.ndarray:
        """Stems per m² whose crowns span heights above the ground.

        Parameters
        ----------
        v : dict
            The parameters' (n,) values and ``density_m2`` (n,) (stems/m²).
        z : array (m)
            Heights above the ground, broadcast against (n, 1).

        Returns
        -------
        array (n, nz) (stems/m²)
            λ·(S(z) − S(z/(1 − ℓ))): a crown of a tree of height h spans [(1 − ℓ)·h, h].
        """
        mean = v["top_height"] - TOP_SDS * v["height_sd"]
        sd, ratio = v["height_sd"][:, None], v["crown_length_ratio"][:, None]
        z = np.maximum(np.asarray(z, float), 0.0)
        mean, t = mean[:, None], self.truncation
        with np.errstate(divide="ignore"):
            base = np.where(ratio < 1.0, z / np.maximum(1.0 - ratio, 0.0), np.inf)
        taller = self.family.sf(z, mean, sd, t) - self.family.sf(base, mean, sd, t)
        return v["density_m2"][:, None] * np.maximum(taller, 0.0)

    def tallest_in_area(self, v, area, uniform) -> np.ndarray:
        """Height of the tallest stem among those of a Poisson stand on an area.

        Parameters
        ----------
        v : dict
            The parameters' (n,) values and ``density_m2`` (n,) (stems/m²).
        area : float (m²)
        uniform : array (n,)
            Uniform variates, one draw per row.

        Returns
        -------
        array (n,) (m)
            The draw of :func:`.tallest_stem.draw_tallest`; 0 where no stem stands. The
            mean of these draws is :func:`forward.derived.expected_max_height`.
        """
        mean = v["top_height"] - TOP_SDS * v["height_sd"]
        tallest, some = tallest_stem.draw_tallest(
            self.family, mean, v["height_sd"], self.truncation, v["density_m2"] * area, uniform
        )
        return np.where(some, tallest, 0.0)

    def lowest_height(self, v) -> np.ndarray:
        """Height of the lowest tree of each row's height family.

        Parameters
        ----------
        v : dict

        Returns
        -------
        array (n,) (m)
        """
        mean = v["top_height"] - TOP_SDS * v["height_sd"]
        return tallest_stem.arguments_and_lowest(
            self.family, mean, v["height_sd"], self.truncation
        )[1]

    def crown_volume_profile(self, v, z) -> np.ndarray:
        """Crown volume per unit ground area and unit height.

        Parameters
        ----------
        v : dict
            Every parameter's (n,) values.
        z : array (m)
            Heights above the ground.

        Returns
        -------
        array (n, nz) (m³/m²/m)
            λ·Σ_s m_s ∫ f(h)·π Rc(h)²·a_s((z − (1 − ℓ)h)/ℓh) dh, a Gauss–Legendre rule over the
            bulk of each row's distribution (a_s the shape's horizontal section).
        """
        z = np.asarray(z, float)
        mean, sd = v["top_height"] - TOP_SDS * v["height_sd"], v["height_sd"]
        _, p, area = self._moments(mean, sd, v)
        lam = poisson_stand.density_from_cover(v["cover"], np.sum(p * area, axis=1))
        mix = np.column_stack([v["cone_fraction"], 1.0 - v["cone_fraction"]])
        return lam[:, None] * self.shape_profile(mean, sd, mix, v, z)
