"""A two-storey stand: the default parameterisation with a lower cohort of trees.

A multi-layer canopy (a tall forest over a sub-canopy, emergents over a closed canopy,
trees over tall shrubs) puts its crowns in two height bands that one truncated-normal
height family cannot hold at once: fitted with one, the waveform's two canopy peaks are
smoothed into one. :class:`TwoCohortMapping` adds a second cohort of the same family, the
lower storey, whose trees share the crowns' radius law, length ratio and FAVD; cohort 2
takes the template's crown-shape mix. Three parameters (:data:`COHORT2`) place it:

- ``cohort2_fraction`` f, the share of the stems in the lower storey (1 − f above);
  emergents over a closed canopy are an upper storey with few stems (f near 1);
- ``cohort2_top_ratio`` ρ, its top height over the upper storey's;
- ``cohort2_sd_ratio`` s, its height sd over its own top height (< 1/TOP_SDS).

The lower cohort lies below the upper one by construction, so the two cannot swap
labels. Cover c and PAI L stay the whole stand's: the Poisson-stand identities of
:mod:`forward.poisson_stand` hold for the mixture of the two height densities, whose
moments are the cohorts' moments weighted by their shares,

    E[π R²] = (1 − f)·E₁[π R²] + f·E₂[π R²],   λ = −ln(1 − c) / E[π R²],

and the same for E[π R² ℓ h] with each cohort's shape mix in the FAVD and crown volume.
"""

import numpy as np

from forward import poisson_stand
from forward.backends import resolve
from forward.crowns import CROWN_SHAPES
from forward.expected import vectors_by_name

from . import tallest_stem
from .mixture_cut import cohort_row, mixture_cut, mixture_sum
from .priors import Uniform
from .stand import DOMINANT_PER_HA, TOP_SDS, StandMapping
from .tallest_stem import TALLEST_STEM, TALLEST_STEM_POSITION

#: The lower storey's parameters: name → (units, description).
COHORT2 = {
    "cohort2_fraction": ("1", "share of the stems in the lower storey (cohort 2)"),
    "cohort2_top_ratio": ("1", "the lower storey's top height over the upper storey's"),
    "cohort2_sd_ratio": ("1", "the lower storey's height sd over its own top height"),
}

#: Default priors of :data:`COHORT2`: the lower storey anywhere from a shrub layer to just
#: below the upper storey's top; its sd from a thin layer to a spread as wide as allowed.
COHORT2_PRIORS = {
    "cohort2_fraction": Uniform(0.0, 1.0),
    "cohort2_top_ratio": Uniform(0.1, 0.9),
    "cohort2_sd_ratio": Uniform(0.02, 0.45),
}

#: Lower-storey parameters that make the two-storey stand the one-storey stand of the
#: same upper storey, but for a lower storey of 0.1 % of the stems: where the nested model
#: lies in this one (its optimum a start for this model's search).
EMPTY_LOWER_STOREY = {"cohort2_fraction": 1e-3, "cohort2_top_ratio": 0.5, "cohort2_sd_ratio": 0.1}


class TwoCohortMapping(StandMapping):
    """The stand mapping of a two-storey stand (see the module).

    Parameters
    ----------
    template : StandParams
        As for :class:`.stand.StandMapping`; its crown-shape mix is cohort 2's.
    shape_pair : (str, str)
    profile_nodes : int
    footprint_sigma_m : float (m) or None
        If set, condition each footprint on its tallest stem within the disc, as
        :class:`.stand.StandMapping` does; the stem's law is that of the tallest of a
        Poisson draw from the mixture of the two storeys, and it stops both.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` for the mixture's cuts (the dominant
        height, the tallest stem: :func:`.mixture_cut.mixture_cut`, compiled for
        truncated-normal heights); the stand columns are computed with numpy.
    """

    def __init__(
        self,
        template,
        shape_pair=("cone", "ellipsoid"),
        profile_nodes=48,
        footprint_sigma_m=None,
        backend="auto",
    ):
        super().__init__(template, shape_pair, profile_nodes, footprint_sigma_m, backend)
        self.backend = "numpy"
        self.cut_backend = resolve(backend)
        self.model_free += ("cohort2_fraction", "cohort2_height_mean", "cohort2_height_sd")
        ratio = dict(zip(CROWN_SHAPES, template.favd_ratio))
        mix2 = dict(zip(CROWN_SHAPES, template.cohort2_shape_mix))
        if any(mix2[s] > 0 for s in CROWN_SHAPES if s not in shape_pair):
            raise ValueError(f"cohort 2's crown shapes must be among {shape_pair}")
        self._mix2_volume = sum(mix2[s] * CROWN_SHAPES[s].volume_fraction for s in shape_pair)
        self._mix2_leaf = sum(
            mix2[s] * ratio[s] * CROWN_SHAPES[s].volume_fraction for s in shape_pair
        )
        self._mix2 = np.array([mix2[s] for s in shape_pair])

    def cohort_heights(self, v):
        """(share, mean, sd) of each cohort, upper storey first (arrays (n,), m)."""
        f = v["cohort2_fraction"]
        top2 = v["cohort2_top_ratio"] * v["top_height"]
        sd2 = v["cohort2_sd_ratio"] * top2
        return (
            (1.0 - f, v["top_height"] - TOP_SDS * v["height_sd"], v["height_sd"]),
            (f, top2 - TOP_SDS * sd2, sd2),
        )

    def valid(self, v) -> np.ndarray:
        """Rows whose parameters describe a stand: those of :class:`.stand.StandMapping`,
        a share f in [0, 1], a top ratio in (0, 1) and a lower storey the family supports."""
        ok = super().valid(v)
        f, ratio, sd_ratio = v["cohort2_fraction"], v["cohort2_top_ratio"], v["cohort2_sd_ratio"]
        ok &= (f >= 0) & (f <= 1) & (ratio > 0) & (ratio < 1)
        ok &= (sd_ratio > 0) & (sd_ratio * TOP_SDS < 1)
        _, (_, mean, sd) = self.cohort_heights(v)
        safe_mean, safe_sd = np.where(ok, mean, 1.0), np.where(ok, sd, 0.1)
        return ok & self.family.valid(safe_mean, safe_sd, self.truncation)

    def _stacked_laws(self, heights):
        """The cohorts' shares (a tuple) and their height laws' arguments
        (``family.arguments``) stacked on a leading cohort axis, of ``heights`` ((share,
        mean, sd) per cohort): every cohort's function in one call (:func:`mixture_sum`)."""
        mean, sd = (np.stack(column) for column in tuple(zip(*heights))[1:])
        shares = tuple(share for share, _, _ in heights)
        return shares, self.family.arguments(mean, sd, self.truncation)

    def _mixture_moments(self, v):
        """Per cohort: share, mean, sd, E[h], E[π R²] and E[π R² ℓ h] (each (n,)); and the
        cohorts' shares and stacked arguments (:meth:`_stacked_laws`). Both cohorts are
        computed in one pass over stacked (2, n) arrays (the same numbers, half the calls)."""
        r0 = self._value(v, "crown_radius_intercept")
        r1, ratio = v["crown_radius_slope"], v["crown_length_ratio"]
        heights = self.cohort_heights(v)
        shares, args = self._stacked_laws(heights)
        m1, m2, m3 = np.moveaxis(self.family.fast("moments", (1, 2, 3), *args), -1, 0)
        area = poisson_stand.crown_area_moment(r0, r1, m1, m2)
        crown = poisson_stand.crown_volume_moment(r0, r1, m1, m2, m3, ratio)
        cohorts = [
            (share, mean, sd, m1[k], area[k], crown[k])
            for k, (share, mean, sd) in enumerate(heights)
        ]
        return cohorts, (shares, args)

    def _mixture_isf(self, laws, tail):
        """The height h where the mixture's survival Σ f_k S_k(h) equals ``tail``; 0
        where ``tail`` ≥ 1 (:func:`.mixture_cut.mixture_cut`, ``laws`` as
        :meth:`_stacked_laws` gives them)."""
        return mixture_cut(self.family, laws, tail, backend=self.cut_backend)

    def _dominant_height(self, laws, lam):
        """Mean height of the :data:`DOMINANT_PER_HA` tallest stems per hectare of the
        mixture (``laws``: :meth:`_stacked_laws`): its cut h* solves λ·Σ f_k S_k(h*) = the
        dominant density (:meth:`_mixture_isf`), then Σ f_k ∫_{h*} h f_k(h) dh over the share above
        the cut."""
        per_m2 = DOMINANT_PER_HA * 1e-4
        tail = np.clip(per_m2 / lam, 1e-9, 1.0)
        cut = self._mixture_isf(laws, tail)
        fast = self.family.fast
        share = mixture_sum(fast, "sf", cut, *laws)
        partial = mixture_sum(fast, "mean_above", cut, *laws)
        return partial / np.maximum(share, 1e-300)

    def _columns(self, v):
        """The cohorts and their laws (:meth:`_mixture_moments`), then λ (stems/m²), crown
        area, mean height, FAVD and crown volume (m³/m²) per row."""
        mixture = self._mixture_moments(v)
        (f1, _, _, m1_1, a1, c1), (f2, _, _, m1_2, a2, c2) = mixture[0]
        cone = v["cone_fraction"]
        volume1 = cone * self._volume[0] + (1.0 - cone) * self._volume[1]
        leaf1 = cone * self._leaf[0] + (1.0 - cone) * self._leaf[1]
        area = f1 * a1 + f2 * a2
        lam = poisson_stand.density_from_cover(v["cover"], area)
        # one volume moment per mixture, each cohort's shape mix inside it
        volume_moment = f1 * c1 * volume1 + f2 * c2 * self._mix2_volume
        leaf_moment = f1 * c1 * leaf1 + f2 * c2 * self._mix2_leaf
        favd = poisson_stand.favd_from_lai(v["pai"], lam, leaf_moment, 1.0)
        volume = poisson_stand.crown_volume(lam, volume_moment, 1.0)
        return mixture, lam, area, f1 * m1_1 + f2 * m1_2, favd, volume

    def model_vectors(self, v):
        """Expected-model vectors and derived quantities (as
        :meth:`.stand.StandMapping.model_vectors`), with cohort 2's share, mean and sd."""
        (cohorts, laws), lam, area, mean_height, favd, volume = self._columns(v)
        (_, mean1, _, *_), (f2, mean2, sd2, *_) = cohorts
        fields = self.stand_fields(v, lam, mean1, favd)
        fields.update(
            {"cohort2_fraction": f2, "cohort2_height_mean": mean2, "cohort2_height_sd": sd2}
        )
        if self.conditioned:
            stem = self._tallest_stem(v, laws, lam)
            fields.update(stem.pop("fields"))
        vectors = vectors_by_name(fields, self.model_free)
        derived = {
            "crown_area": area,
            "density": lam * 1e4,
            "favd": favd,
            "mean_height": mean_height,
            "dominant_height": self._dominant_height(laws, lam),
            "crown_volume": volume * 1e4,
            "lai": v["pai"] + v["understory_lai"],
        }
        if self.conditioned:
            derived.update(stem)
        return vectors, derived

    def _tallest_stem(self, v, laws, lam) -> dict:
        """:func:`.tallest_stem.condition` on the mixture of the two storeys (``laws``:
        :meth:`_stacked_laws`)."""
        shares, args = laws
        per_cohort = [(f, cohort_row(args, k)) for k, f in enumerate(shares)]
        return tallest_stem.condition(
            self.family, per_cohort, self.lowest_height(v), lam * self.tallest_stem_area,
            v[TALLEST_STEM], v[TALLEST_STEM_POSITION], self.footprint_sigma_m,
        )  # fmt: skip

    def _per_cohort(self, v, method, *args):
        """Σ over cohorts of a single-cohort method, each on its own heights and stems."""
        total = 0.0
        for share, mean, sd in self.cohort_heights(v):
            one = {**v, "top_height": mean + TOP_SDS * sd, "height_sd": sd}
            one["density_m2"] = v["density_m2"] * share
            total = total + getattr(super(), method)(one, *args)
        return total

    def crowns_spanning(self, v, z) -> np.ndarray:
        """Stems per m² whose crowns span heights z above the ground (both storeys)."""
        return self._per_cohort(v, "crowns_spanning", z)

    def tallest_in_area(self, v, area, uniform) -> np.ndarray:
        """Height of the tallest stem of a Poisson stand on an area (m; 0 where none):
        the mixture's S(h) = −ln U / N solved by bisection."""
        with np.errstate(divide="ignore"):
            tail = poisson_stand.tallest_survival(uniform, v["density_m2"] * area)
        return self._mixture_isf(self._stacked_laws(self.cohort_heights(v)), tail)

    def lowest_height(self, v) -> np.ndarray:
        """Height of the lowest tree of either storey (m)."""
        return np.minimum(
            *(
                tallest_stem.arguments_and_lowest(self.family, mean, sd, self.truncation)[1]
                for _, mean, sd in self.cohort_heights(v)
            )
        )

    def crown_volume_profile(self, v, z) -> np.ndarray:
        """Crown volume per unit ground area and unit height (m³/m²/m), both storeys:
        each storey's profile (:meth:`.stand.StandMapping.shape_profile`) times the
        stand's density and the storey's share of the stems."""
        _, lam, *_ = self._columns(v)
        z = np.asarray(z, float)
        mixes = (np.column_stack([v["cone_fraction"], 1.0 - v["cone_fraction"]]), self._mix2)
        out = np.zeros((lam.size, z.size))
        for (share, mean, sd), mix in zip(self.cohort_heights(v), mixes):
            out += share[:, None] * self.shape_profile(mean, sd, mix, v, z)
        return lam[:, None] * out
