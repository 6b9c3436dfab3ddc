"""From inversion parameters to the expected-waveform model, and the derived quantities.

Cover c and crown plant area index L fix stem density and FAVD through the Poisson-stand
identities (for a height density f and crown radius R(h) = r0 + r1·h; the expectations
are closed forms in the raw moments E[h^k] of the height family):

    c = 1 − exp(−λ·E[π R²])             →  λ = −ln(1 − c) / E[π R²]   (stems/m²)
    L = λ·FAVD·Σ_s m_s κ_s v_s E[π R² ℓ h]  →  FAVD = L / (λ·Σ …)     (m²/m³)

with m_s the shape fractions, κ_s the per-shape FAVD ratios, v_s the volume fractions of
the shapes and ℓ the crown length ratio. The top height is mean + 2·sd of the height
family: for the default truncated normal (truncated at ±2 sd) it is the tallest tree.
The crown-volume profile, whose integrand has kinks at the crown ends, uses Gauss–Legendre
quadrature on the bulk of each row's distribution.
"""

import numpy as np

from forward.crowns import CROWN_SHAPES
from forward.expected import MIX_FIELDS, VECTOR_FIELDS
from forward.expected.vectors import CONDITIONING_FIELDS
from forward.stand_params import HEIGHT_DISTRIBUTIONS, StandParams

from . import compiled_stand

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

#: Stems per hectare whose mean height is the dominant height.
DOMINANT_PER_HA = 100.0

#: The latent parameter of a footprint conditioned on its tallest stem: that stem's height
#: H (m), whose law given the stand is the Poisson order statistic
#: (:meth:`StandMapping.tallest_stem_log_density`); H below the stand's lowest tree stands
#: for a disc without a stem.
TALLEST_STEM = "tallest_stem_height"

#: Depth (m) of the range of H just below the stand's lowest tree that stands for a disc
#: without a stem, which spreads the chance of none, e^{−λA}, uniformly over it. Joined to
#: the support, it lets the sampler pass between a short stem and none.
NO_STEM_DEPTH_M = 1.0

#: The latent position of that stem: its squared distance from the footprint centre over
#: the disc's squared radius, uniform a priori; it sets the stem's footprint weight.
TALLEST_STEM_POSITION = "tallest_stem_position"

#: The latent parameters of a footprint conditioned on its tallest stem.
TALLEST_STEM_LATENTS = (TALLEST_STEM, TALLEST_STEM_POSITION)

#: Radius (in footprint σ) of the disc whose tallest stem conditions the footprint: the
#: 1/e² radius, holding 1 − e⁻² of the footprint's weight.
TALLEST_STEM_RADIUS_SIGMAS = 2.0

#: The position V whose footprint weight exp(−2V) is the disc's mean, (1 − e⁻²)/2: where V
#: is held there, the realisation covariance carries the spread of the stem's weight.
TALLEST_STEM_MEAN_POSITION = -0.5 * np.log(0.5 * (1.0 - np.exp(-2.0)))


def default_template(shape_pair=("cone", "ellipsoid")) -> StandParams:
    """Template stand for the default parameterisation (truncated-normal heights)."""
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
        R = :data:`TALLEST_STEM_RADIUS_SIGMAS`·σf (area A): the parameters then include
        the latents :data:`TALLEST_STEM_LATENTS`: the stem's height H (m), whose law
        given the stand is that of the tallest of a Poisson(λA) draw of stems
        (:meth:`tallest_stem_log_density`), and V, uniform a priori: the stem stands at
        r² = V·R² from the centre.
        Cohort 1 stops at H (``height_cap``) and the stem itself is an apex cohort whose
        density is its footprint weight, exp(−r²/2σf²)/(2πσf²) stems per m²
        (``apex_density``; on average over V, the disc's weight 1 − e⁻² over A). Stems
        outside the disc are capped too, an approximation worth e⁻² of the weight.
    """

    def __init__(
        self,
        template: StandParams,
        shape_pair=("cone", "ellipsoid"),
        profile_nodes=48,
        footprint_sigma_m=None,
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
        #: model_vectors through :mod:`.compiled_stand` (truncated-normal heights only)
        self.compiled = template.height_family == "truncnorm"
        assert all(f in MIX_FIELDS for f in self.model_free[len(MODEL_FIELDS) :])
        #: whether footprints are conditioned on their tallest stem (and its disc's area)
        self.conditioned = footprint_sigma_m is not None
        if self.conditioned:
            if not (np.isfinite(footprint_sigma_m) and footprint_sigma_m > 0):
                raise ValueError(f"footprint_sigma_m must be positive, got {footprint_sigma_m}")
            radius = TALLEST_STEM_RADIUS_SIGMAS * float(footprint_sigma_m)
            self.tallest_stem_area = np.pi * radius**2
            self._apex_per_ha = 1e4 / (2.0 * np.pi * float(footprint_sigma_m) ** 2)
            self.model_free += tuple(CONDITIONING_FIELDS)

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

    def _moments(self, v):
        mean, sd = v["top_height"] - TOP_SDS * v["height_sd"], v["height_sd"]
        h, weight = self._quadrature(mean, sd)
        total = weight.sum(axis=1)
        p = weight / np.where(total > 0, total, 1.0)[:, None]
        radius = self.template.crown_radius_intercept + v["crown_radius_slope"][:, None] * h
        area = np.pi * radius**2
        return mean, sd, h, p, area

    def valid(self, v) -> np.ndarray:
        """Rows whose parameters describe a stand (before any model evaluation)."""
        mean, sd = v["top_height"] - TOP_SDS * v["height_sd"], v["height_sd"]
        ok = (mean > 0) & (sd > 0) & (v["cover"] > 0) & (v["cover"] < 1) & (v["pai"] > 0)
        ok &= (v["crown_length_ratio"] > 0) & (v["crown_length_ratio"] <= 1)
        ok &= (v["cone_fraction"] >= 0) & (v["cone_fraction"] <= 1)
        ok &= (v["understory_height"] > 0) & (v["understory_lai"] >= 0)
        ok &= (v["rho_ratio"] >= 0) & (v["crown_radius_slope"] > 0)
        safe_mean, safe_sd = np.where(ok, mean, 1.0), np.where(ok, sd, 0.1)
        return ok & self.family.valid(safe_mean, safe_sd, self.truncation)

    def model_vectors(self, v):
        """Expected-model vectors (n, len(model_free)) and scalar derived quantities.

        ``v`` maps every parameter name to an (n,) array; rows must be :meth:`valid`.
        Expectations over heights are closed forms of the raw moments E[h^k], k ≤ 3;
        truncated-normal heights take the compiled path (:mod:`.compiled_stand`).
        """
        if self.compiled:
            columns = compiled_stand.stand_columns(
                v,
                self.template.crown_radius_intercept,
                TOP_SDS,
                self.truncation,
                self._volume,
                self._leaf,
                DOMINANT_PER_HA,
            )
            lam, mean, favd, area, m1, volume, dominant = columns.T
        else:
            lam, mean, favd, area, m1, volume, dominant = self._stand_columns(v)
        cone = v["cone_fraction"]
        vectors = np.column_stack(
            [
                lam * 1e4,
                mean,
                v["height_sd"],
                v["crown_length_ratio"],
                np.full_like(mean, self.template.crown_radius_intercept),
                v["crown_radius_slope"],
                favd,
                v["understory_height"],
                v["understory_lai"],
                v["rho_ratio"],
                np.ones_like(mean),
                v["ground_elevation"],
                cone,
                1.0 - cone,
            ]
        )
        if self.conditioned:
            args, lowest = self._arguments_and_lowest(mean, v["height_sd"])
            tallest = v[TALLEST_STEM]
            some = tallest >= lowest
            cap = np.where(some, tallest, 1e-6)  # no stem in the disc: no tree below the cap
            weight = np.exp(-0.5 * TALLEST_STEM_RADIUS_SIGMAS**2 * v[TALLEST_STEM_POSITION])
            apex = np.where(some, self._apex_per_ha * weight, 0.0)
            vectors = np.column_stack([vectors, cap, apex])
        derived = {
            "crown_area": area,  # m², not a blob: for the discrepancy model
            "density": lam * 1e4,
            "favd": favd,
            "mean_height": m1,
            "dominant_height": dominant,
            "crown_volume": volume * 1e4,
            "lai": v["pai"] + v["understory_lai"],
        }
        if self.conditioned:  # m, 0 where the disc holds no stem
            derived["tallest_stem"] = np.where(some, tallest, 0.0)
            derived["tallest_stem_log_density"] = self.tallest_stem_log_density(
                args, lowest, lam * self.tallest_stem_area, tallest
            )
        return vectors, derived

    def _stand_columns(self, v):
        """Density (stems/m²), mean of the parent normal (m), FAVD (m²/m³), crown area
        E[π R²] (m²), mean height (m), crown volume (m³/m²) and dominant height (m) per
        row, in numpy for any height family (the reference of the compiled path)."""
        mean, sd = v["top_height"] - TOP_SDS * v["height_sd"], v["height_sd"]
        m1, m2, m3 = np.moveaxis(
            self.family.raw_moments((1, 2, 3), mean, sd, self.truncation), -1, 0
        )
        r0, r1 = self.template.crown_radius_intercept, v["crown_radius_slope"]
        mix = np.column_stack([v["cone_fraction"], 1.0 - v["cone_fraction"]])
        per_stem_area = np.pi * (r0 * r0 + 2.0 * r0 * r1 * m1 + r1 * r1 * m2)  # E[π R²]
        crown_volume = (
            np.pi * (r0 * r0 * m1 + 2.0 * r0 * r1 * m2 + r1 * r1 * m3) * v["crown_length_ratio"]
        )  # E[π R² ℓ h]
        lam = -np.log1p(-v["cover"]) / per_stem_area
        volume = lam * crown_volume * (mix @ self._volume)
        favd = v["pai"] / (lam * crown_volume * (mix @ self._leaf))
        dominant = self._dominant_height(mean, sd, lam * 1e4)
        return lam, mean, favd, per_stem_area, m1, volume, dominant

    def crowns_spanning(self, v, z) -> np.ndarray:
        """Stems per m² whose crowns span height ``z`` (m above the ground), (n, nz).

        A crown of a tree of height h spans [(1 − ℓ)·h, h], so the trees are those with
        z ≤ h ≤ z/(1 − ℓ); ``v`` holds ``density_m2`` (n,) besides the parameters.
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
        """Height (m) of the tallest stem among those of a Poisson stand on ``area`` (m²),
        one draw per row from uniform variates ``uniform`` (n,); 0 where no stem stands.

        With N ~ Poisson(λ·area) stems of height survival S(h), the tallest one has
        P(max ≤ h) = exp(−λ·area·S(h)), so a draw solves S(h) = −ln U / (λ·area).
        ``v`` holds ``density_m2`` (n,) besides the parameters. The mean of these draws
        is :func:`forward.derived.expected_max_height`.
        """
        mean = v["top_height"] - TOP_SDS * v["height_sd"]
        tallest, some = self._tallest(mean, v["height_sd"], v["density_m2"] * area, uniform)
        return np.where(some, tallest, 0.0)

    def tallest_stem_log_density(self, args, lowest, stems, tallest) -> np.ndarray:
        """Log density (1/m) of the tallest stem's height H (m) in a disc holding
        Poisson(``stems``) stems of height density f and survival S (the height family of
        arguments ``args``, whose lowest tree is ``lowest``, m): P(max ≤ h) =
        exp(−stems·S(h)), so H has the density stems·f(H)·exp(−stems·S(H)) on the
        family's support, and the chance of no stem, e^{−stems}, is spread over the
        :data:`NO_STEM_DEPTH_M` below ``lowest``; −inf elsewhere."""
        some = tallest >= lowest
        height = np.where(some, tallest, lowest)
        with np.errstate(divide="ignore"):
            law = np.log(stems * self.family.fast("pdf", height, *args))
        law -= stems * self.family.fast("sf", height, *args)
        none = np.where(tallest >= lowest - NO_STEM_DEPTH_M, -np.log(NO_STEM_DEPTH_M), -np.inf)
        return np.where(some, law, none - stems)

    def lowest_height(self, v) -> np.ndarray:
        """Height (m) of the lowest tree of each row's height family, (n,)."""
        mean = v["top_height"] - TOP_SDS * v["height_sd"]
        return self._arguments_and_lowest(mean, v["height_sd"])[1]

    def _arguments_and_lowest(self, mean, sd):
        """The height family's arguments and its lowest tree's height (m) per row."""
        args = self.family.arguments(mean, sd, self.truncation)
        return args, self.family.fast("ppf", np.zeros_like(mean), *args)

    def _tallest(self, mean, sd, stems, uniform):
        """Height (m) solving S(h) = −ln U / ``stems`` (the expected stems on the area) and
        whether any stem stands there; where none does, the lowest height of the family."""
        with np.errstate(divide="ignore"):
            tail = -np.log(uniform) / stems
        some = tail < 1.0
        args = self.family.arguments(mean, sd, self.truncation)
        return self.family.fast("isf", np.minimum(tail, 1.0), *args), some

    def _dominant_height(self, mean, sd, density):
        """Mean height of the DOMINANT_PER_HA tallest stems per hectare (all if fewer):
        the family's closed-form partial mean above the cut over the share above it, which
        is the tail the cut was taken at."""
        tail = np.clip(DOMINANT_PER_HA / density, 1e-9, 1.0)
        args = self.family.arguments(mean, sd, self.truncation)
        cut = self.family.fast("isf", tail, *args)
        return self.family.fast("mean_above", cut, *args) / tail

    def crown_volume_profile(self, v, z) -> np.ndarray:
        """Crown volume per unit ground area and height (m³/m²/m) at heights z (m), (n, nz)."""
        z = np.asarray(z, float)
        mean, _sd, h, p, area = self._moments(v)
        ratio = v["crown_length_ratio"][:, None, None]
        mix = np.column_stack([v["cone_fraction"], 1.0 - v["cone_fraction"]])
        lam = -np.log1p(-v["cover"]) / np.sum(p * area, axis=1)
        length = ratio * h[:, None, :]
        s = (z[None, :, None] - (h[:, None, :] - length)) / length
        out = np.zeros((mean.size, z.size))
        for k, shape in enumerate(self.shape_pair):
            section = CROWN_SHAPES[shape].section(s)
            out += mix[:, k, None] * np.sum((p * area)[:, None, :] * section, axis=2)
        return lam[:, None] * out
