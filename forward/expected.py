r"""The expected waveform of a Poisson stand: a fast forward model for inversion.

Derivation
----------
Let the stems form a Poisson process of intensity λ (stems/m²) with independent marks
(height h, shape, FAVD u; crown length Lc = c·h and radius Rc(h) follow the allometry).
Foliage densities of overlapping crowns add, so at a point (x, z) the optical depth above
z is a sum over trees, τ(x, z) = Σ_i κ·u_i·ℓ_i(x, z) with κ = k·G·Ω and ℓ_i the path
length through crown i above z. The probability generating functional of a marked Poisson
process gives

    E[P(x, z)] = E[Π_i exp(−κ u_i ℓ_i)] = exp(−λ · E_mark[∫ (1 − exp(−κ u ℓ(r, z; h))) dA]),

independent of x (stationarity). The waveform is linear in the footprint-weighted mean
gap P̄(z) = ∫ w(x) P(x, z) dA with ∫ w = 1, so E[P̄(z)] = E[P(x, z)] for any footprint and
the expected waveform follows from E[P] at the fine-layer edges: a canopy layer returns
ρv·ΔE[P] and the ground ρg·E[P(0)] (physics conventions, "Radiative transfer").

Inner integral. With ρ = r/Rc and a crown interval [s_lo(ρ), s_hi(ρ)] (fractions of Lc
above the base (1 − c)h), a column at ρ crosses the crown between a(ρ)·h and b(ρ)·h with
a = 1 − c + c·s_lo and b = 1 − c + c·s_hi: both ends are proportional to h. With
Gauss–Legendre nodes ρ_j across the disc (weights w_j, Σ w_j = 1, area dA = π Rc² d(ρ²);
in ρ for cones and cylinders, in sqrt(1 − ρ²) for spheroids, see
:func:`forward.expected_tables.radial_rule`) and the cohort/shape height density f_s(h),

    λ E[∫(1 − e^{−κuℓ}) dA] = Σ_s Σ_j w_j ∫ g_s(h) · φ_j(z, h) dh,  g_s = λ π Rc(h)² f_s(h),

    φ_j = 0                                 for h < z/b_j   (crown top below z)
        = 1 − exp(−κu (b_j h − z))          for z/b_j ≤ h < z/a_j
        = 1 − exp(−κu (b_j − a_j) h)         for h ≥ z/a_j   (whole chord above z).

So the height integral is exact given three tail integrals on a height grid,
Q0(t) = ∫_t^∞ g, Q1_j(t) = ∫_t^∞ g e^{−κu(b_j−a_j)h}, Q2_j(t) = ∫_t^∞ g e^{−κu b_j h}:

    ∫ g φ_j dh = Q0(z/b_j) − Q1_j(z/a_j) − e^{κuz} [Q2_j(z/b_j) − Q2_j(z/a_j)].

A call builds these tables per parameter vector and cohort (``height_nodes`` points over
the cohort's height distribution, fourth-order rules of
:class:`forward.expected_tables.TailTable`), reads them at z/a_j and z/b_j on
``depth_nodes`` heights from 0 to the tallest tree, interpolates E[P] to every fine-layer
edge (Catmull–Rom; or reads the tables at every edge when ``depth_nodes`` is None), and
convolves the layer returns ρv·ΔE[P] with the same layer kernel as the explicit engine
(:func:`forward.pulse.layer_kernel`) as one matrix product. The ground elevation g moves
the edges (z = e − g): no resampling of samples. The uniform
understory multiplies E[P] by its own transmission; the ground pulse is ρg·E[P(0)]·Δz·
pulse(z_j − g), for a Gaussian or a measured pulse alike. Slopes are not modelled here.
"""

from dataclasses import dataclass

import numpy as np

from .crowns import CROWN_SHAPES, SHAPE_NAMES
from .expected_tables import TailTable, catmull_rom, exp_grid, grid_position, radial_rule
from .pulse import layer_kernel
from .stand_params import HEIGHT_DISTRIBUTIONS, StandParams

#: Every quantity a parameter vector may carry, in the order of the model's full vector.
VECTOR_FIELDS = (
    "density",
    "height_mean",
    "height_sd",
    "cohort2_fraction",
    "cohort2_height_mean",
    "cohort2_height_sd",
    "crown_length_ratio",
    "crown_radius_intercept",
    "crown_radius_slope",
    "favd",
    "understory_height",
    "understory_lai",
    "canopy_reflectance",
    "ground_reflectance",
    "ground_elevation",
) + tuple(f"mix_{name}" for name in SHAPE_NAMES)

#: Vector fields holding cohort 1's crown-shape fractions (≥ 0, summing to 1).
MIX_FIELDS = tuple(f"mix_{name}" for name in SHAPE_NAMES)

#: The default free parameters of :class:`ExpectedWaveformModel` (its vector layout).
DEFAULT_FREE = (
    "density",
    "height_mean",
    "height_sd",
    "crown_length_ratio",
    "crown_radius_slope",
    "favd",
    "canopy_reflectance",
    "ground_reflectance",
    "ground_elevation",
)

_I = {name: i for i, name in enumerate(VECTOR_FIELDS)}


@dataclass(frozen=True)
class ModelSettings:
    """Numerical settings of the expected model.

    Parameters
    ----------
    radial_nodes : int
        Gauss–Legendre nodes in ρ² across the crown disc.
    height_nodes : int
        Grid points of the height tables.
    tail : float
        Height-distribution probability left out in each tail of the grid.
    oversampling : int or None
        Fine layers per bin; ``None`` uses the explicit engine's rule (layers ≤ σz/4).
    depth_nodes : int or None
        ``None``: evaluate the tree optical depth at every fine-layer edge. An integer:
        evaluate it on that many heights from 0 to the tallest tree and interpolate to the
        edges by cubic Hermite (Catmull–Rom) interpolation: much cheaper, and smooth
        because the depth is already averaged over the height distribution.
    max_elements : int
        Rows are processed in chunks so that no work array exceeds this many elements.
    """

    radial_nodes: int = 6
    height_nodes: int = 32
    tail: float = 1e-6
    oversampling: int | None = None
    depth_nodes: int | None = 32
    max_elements: int = 4_000_000


#: Settings taken as converged (the reference of the benchmark and the convergence test).
CONVERGED = ModelSettings(radial_nodes=48, height_nodes=1024, tail=1e-9, depth_nodes=None)


@dataclass(frozen=True)
class ExpectedWaveforms:
    """Output of :meth:`ExpectedWaveformModel.evaluate` (arrays of shape (n, n_bins)).

    ``samples = canopy + ground``; rows with ``valid`` False hold zeros.
    ``gap_ground`` (n,) is E[P(0)].
    """

    samples: np.ndarray
    canopy: np.ndarray
    ground: np.ndarray
    gap_ground: np.ndarray
    valid: np.ndarray


def engine_oversampling(instrument):
    """Fine layers per bin chosen by the explicit engine's default rule (layer ≤ σz/4)."""
    low, high = instrument.pulse.support(0.1587)
    return max(1, int(np.ceil(8.0 * instrument.bin_height / max(high - low, 1e-12))))


class ExpectedWaveformModel:
    """Expected waveform E[W | θ] of Poisson stands, batched over parameter vectors.

    Parameters
    ----------
    instrument : Instrument
        Pulse (Gaussian or measured), bins and κ = k·G·Ω; the footprint size does not
        enter the expectation.
    heights : array (m)
        Bin centres on the absolute height axis, ascending in steps of the bin height.
    template : StandParams
        Values of everything that is not free: height family, shape mixes, FAVD ratios,
        truncation, and the fixed numbers.
    free : tuple of str
        Names from :data:`VECTOR_FIELDS` forming the parameter vector, in order.
    settings : ModelSettings
    """

    def __init__(
        self,
        instrument,
        heights,
        template: StandParams,
        free=DEFAULT_FREE,
        settings: ModelSettings | None = None,
    ):
        self.settings = ModelSettings() if settings is None else settings
        unknown = [name for name in free if name not in _I]
        if unknown:
            raise ValueError(f"unknown free parameter(s) {unknown}; choose from {VECTOR_FIELDS}")
        self.instrument = instrument
        self.template = template
        self.parameter_names = tuple(free)
        self._free_index = np.array([_I[name] for name in free], np.intp)
        self._base = self.full_vector(template)
        heights = np.asarray(heights, float)
        dz = instrument.bin_height
        if heights.ndim != 1 or heights.size < 2 or np.max(np.abs(np.diff(heights) - dz)) > 1e-6:
            raise ValueError("heights must ascend in steps of the instrument's bin height")
        self.heights = heights
        s = self.settings
        m = engine_oversampling(instrument) if s.oversampling is None else int(s.oversampling)
        self.oversampling = m
        self.layer_height = dz / m
        q_min, taps = layer_kernel(instrument.pulse, dz, m, 1e-9)
        # layers that reach a window bin: q = j·m − i within [q_min, q_min + len − 1]
        q_max = q_min + taps.size - 1
        self._layer0 = -q_max
        n_layers = (heights.size - 1) * m - q_min - self._layer0 + 1
        i = self._layer0 + np.arange(n_layers)
        q = np.arange(heights.size)[None, :] * m - i[:, None]
        inside = (q >= q_min) & (q <= q_max)
        self._kernel = np.where(inside, taps[np.clip(q - q_min, 0, taps.size - 1)], 0.0)
        origin = heights[0] - dz / 2
        self._edges = origin + (self._layer0 + np.arange(n_layers + 1)) * self.layer_height
        # radial quadrature and the per-shape chord fractions
        mixes = np.array([template.shape_mix, template.cohort2_shape_mix])
        free_mix = [f"mix_{name}" in self.parameter_names for name in SHAPE_NAMES]
        self._shapes = [k for k in range(len(SHAPE_NAMES)) if mixes[:, k].any() or free_mix[k]]
        self._mixes = mixes
        self._s_lo, self._s_hi, self._weights = [], [], []
        for k in self._shapes:
            rho, weights = radial_rule(SHAPE_NAMES[k], s.radial_nodes)
            lo, hi = CROWN_SHAPES[SHAPE_NAMES[k]].extent(rho)
            self._weights.append(weights)
            self._s_lo.append(np.asarray(lo, float))
            self._s_hi.append(np.asarray(hi, float))
        self._family = HEIGHT_DISTRIBUTIONS[template.height_family]
        self._kappa = instrument.extinction_per_favd

    # vectors ---------------------------------------------------------------------------
    @property
    def ndim(self) -> int:
        return len(self.parameter_names)

    def full_vector(self, params: StandParams, ground_elevation=0.0) -> np.ndarray:
        """All of :data:`VECTOR_FIELDS` for one parameter object."""
        values = params.as_dict()
        values["ground_elevation"] = ground_elevation
        values.update(zip(MIX_FIELDS, params.shape_mix))
        return np.array([float(values[name]) for name in VECTOR_FIELDS])

    def vector(self, params: StandParams, ground_elevation=0.0) -> np.ndarray:
        """The free-parameter vector of ``params`` (checks that its fixed settings match)."""
        for name in (
            "height_family",
            "shape_mix",
            "cohort2_shape_mix",
            "favd_ratio",
            "height_truncation",
        ):
            if name == "shape_mix" and set(MIX_FIELDS) & set(self.parameter_names):
                continue  # the mix is (partly) free
            if getattr(params, name) != getattr(self.template, name):
                raise ValueError(f"{name} differs from the model's template; build a new model")
        return self.full_vector(params, ground_elevation)[self._free_index]

    def _full(self, theta):
        if isinstance(theta, StandParams):
            theta = [theta]
        if isinstance(theta, (list, tuple)) and theta and isinstance(theta[0], StandParams):
            theta = np.array([self.vector(p) for p in theta])
        theta = np.atleast_2d(np.asarray(theta, float))
        if theta.ndim != 2 or theta.shape[1] != self.ndim:
            raise ValueError(f"theta must have shape (n, {self.ndim}), got {theta.shape}")
        full = np.repeat(self._base[None, :], theta.shape[0], axis=0)
        full[:, self._free_index] = theta
        return full

    def valid(self, theta) -> np.ndarray:
        """True for rows that are physical parameter vectors."""
        return self._valid(self._full(theta))

    def _valid(self, v):
        ok = np.all(np.isfinite(v), axis=1)
        v = np.where(np.isfinite(v), v, 1.0)
        col = lambda name: v[:, _I[name]]  # noqa: E731
        ok &= (col("density") >= 0) & (col("height_mean") > 0) & (col("height_sd") > 0)
        ok &= (col("cohort2_fraction") >= 0) & (col("cohort2_fraction") <= 1)
        ok &= (col("crown_length_ratio") > 0) & (col("crown_length_ratio") <= 1)
        ok &= (col("crown_radius_intercept") >= 0) & (col("crown_radius_slope") > 0)
        ok &= (col("favd") > 0) & (col("understory_height") > 0) & (col("understory_lai") >= 0)
        ok &= (col("canopy_reflectance") >= 0) & (col("ground_reflectance") >= 0)
        mix = v[:, [_I[name] for name in MIX_FIELDS]]
        ok &= np.all(mix >= 0, axis=1) & (np.abs(mix.sum(axis=1) - 1.0) < 1e-6)
        t = self.template.height_truncation
        ok &= self._family.valid(col("height_mean"), col("height_sd"), t)
        two = col("cohort2_fraction") > 0
        c2_ok = (col("cohort2_height_mean") > 0) & (col("cohort2_height_sd") > 0)
        ok &= ~two | (
            c2_ok
            & self._family.valid(
                np.abs(col("cohort2_height_mean")) + 1e-9, np.abs(col("cohort2_height_sd")), t
            )
        )
        return ok

    # evaluation --------------------------------------------------------------------------
    def __call__(self, theta) -> np.ndarray:
        """Expected waveforms, shape (n, n_bins); invalid rows are zeros (see ``valid``)."""
        return self.evaluate(theta).samples

    def evaluate(self, theta) -> ExpectedWaveforms:
        """Expected waveforms with their canopy/ground parts and a validity mask."""
        full = self._full(theta)
        valid = self._valid(full)
        full[~valid] = self._base
        n = full.shape[0]
        s = self.settings
        per_row = len(self._shapes) * s.radial_nodes * max(s.height_nodes, self._edges.size)
        chunk = max(1, s.max_elements // max(per_row, 1))
        canopy = np.empty((n, self.heights.size))
        gap0 = np.empty(n)
        for start in range(0, n, chunk):
            rows = slice(start, start + chunk)
            canopy[rows], gap0[rows] = self._canopy(full[rows])
        g = full[:, _I["ground_elevation"]]
        dz = self.instrument.bin_height
        low, high = self.instrument.pulse.support(1e-12)
        first = max(int(np.searchsorted(self.heights, g.min() + low)), 0)
        last = int(np.searchsorted(self.heights, g.max() + high, side="right"))
        ground = np.zeros_like(canopy)
        if last > first:
            pulse = self.instrument.pulse.pdf(self.heights[None, first:last] - g[:, None])
            ground[:, first:last] = (full[:, _I["ground_reflectance"]] * gap0)[:, None] * dz * pulse
        canopy *= full[:, _I["canopy_reflectance"]][:, None]
        canopy[~valid] = 0.0
        ground[~valid] = 0.0
        return ExpectedWaveforms(canopy + ground, canopy, ground, gap0, valid)

    def gap(self, theta, z) -> np.ndarray:
        """E[P(z)] at heights ``z`` (m above the ground), shape (n, len(z))."""
        full = self._full(theta)
        z = np.broadcast_to(np.asarray(z, float), (full.shape[0], np.size(z)))
        return self._gap(full, z)

    def _canopy(self, v):
        g = v[:, _I["ground_elevation"]]
        # only edges that can hold canopy for some row need the tables
        cohorts = self._cohorts(v)
        top = self._top(cohorts)
        lo_edge = np.searchsorted(self._edges, g.min(), side="right") - 1
        hi_edge = np.searchsorted(self._edges, (g + top).max(), side="right") + 1
        lo_edge, hi_edge = max(lo_edge, 0), min(hi_edge, self._edges.size - 1)
        canopy = np.zeros((v.shape[0], self.heights.size))
        z = self._edges[None, lo_edge : hi_edge + 1] - g[:, None]
        z = np.concatenate([np.zeros((v.shape[0], 1)), z], axis=1)
        p = self._gap(v, z, cohorts)
        if hi_edge > lo_edge:
            energy = np.diff(p[:, 1:], axis=1)
            canopy = energy @ self._kernel[lo_edge:hi_edge]
        return canopy, p[:, 0]

    def _cohorts(self, v):
        """Per cohort: (weight, mean, sd, lo, hi), with the grid span [lo, hi] (m)."""
        t, tail = self.template.height_truncation, self.settings.tail
        out = []
        for weight, mean, sd in self._cohort_columns(v):
            lo = self._family.ppf(tail, mean, sd, t)
            hi = np.maximum(self._family.isf(tail, mean, sd, t), lo + 1e-6)
            out.append((weight, mean, sd, lo, hi))
        return out

    @staticmethod
    def _top(cohorts):
        """Tallest tree of any active cohort (m), per row."""
        return np.max([np.where(w > 0, hi, 0.0) for w, _, _, _, hi in cohorts], axis=0)

    def _cohort_columns(self, v):
        f2 = v[:, _I["cohort2_fraction"]]
        yield 1.0 - f2, v[:, _I["height_mean"]], v[:, _I["height_sd"]]
        if self.template.cohort2_fraction > 0 or "cohort2_fraction" in self.parameter_names:
            safe = f2 > 0
            yield (
                f2,
                np.where(safe, v[:, _I["cohort2_height_mean"]], 1.0),
                np.where(safe, v[:, _I["cohort2_height_sd"]], 0.1),
            )

    def _gap(self, v, z, cohorts=None):
        """E[P] at heights z (n, e) above the ground, for full vectors v (n, …)."""
        z = np.maximum(z, 0.0)
        cohorts = self._cohorts(v) if cohorts is None else cohorts
        nodes = self.settings.depth_nodes
        if nodes is None:
            gap = np.exp(-self._tree_depth(v, z, cohorts))
        else:  # E[P] of the trees on a uniform grid from 0 to the tallest tree, then cubic
            top = self._top(cohorts)
            grid = top[:, None] * np.linspace(0.0, 1.0, nodes)
            depth = self._tree_depth(v, grid, cohorts, uniform=True)
            gap = catmull_rom(np.exp(-depth), z, top / (nodes - 1), beyond=1.0)
        lai = v[:, _I["understory_lai"], None]
        if np.any(lai > 0):  # the uniform layer multiplies every column's gap
            hu = v[:, _I["understory_height"], None]
            gap = gap * np.exp(-self._kappa * lai * np.clip(hu - z, 0.0, None) / hu)
        return gap

    def _tree_depth(self, v, z, cohorts, uniform=False):
        """λ·E[∫(1 − e^{−κuℓ}) dA] at heights z ≥ 0 (n, e), for full vectors v (n, …).

        ``uniform``: z is a uniform grid per row starting at 0 (exponentials by products).

        Each cohort gets its own height grid, spanning its own distribution, so that a
        truncated distribution has its jumps only at the grid ends.
        """
        n, s = v.shape[0], self.settings
        nh = s.height_nodes
        t = self.template.height_truncation
        c = v[:, _I["crown_length_ratio"], None]
        favd = self.template.favd_by_shape() / self.template.favd
        depth = np.zeros_like(z)
        rows = (np.arange(n) * nh)[:, None, None]
        for cohort, (weight, mean, sd, lo, hi) in enumerate(cohorts):
            step = (hi - lo) / (nh - 1)
            h = lo[:, None] + step[:, None] * np.arange(nh)
            pdf = self._family.pdf(h, mean[:, None], sd[:, None], t)
            norm = TailTable(pdf, step).q[:, 0]
            radius = (
                v[:, _I["crown_radius_intercept"], None] + v[:, _I["crown_radius_slope"], None] * h
            )
            scale = np.pi * v[:, _I["density"]] / 1e4 * weight / np.where(norm > 0, norm, 1.0)
            g_cohort = scale[:, None] * radius**2 * pdf
            inv = (1.0 / step)[:, None, None]
            for k, shape in enumerate(self._shapes):
                if cohort == 0:  # cohort 1's mix is part of the vector
                    fraction = v[:, _I[MIX_FIELDS[shape]], None]
                else:
                    fraction = self._mixes[cohort, shape]
                if not np.any(fraction):
                    continue
                g_h = fraction * g_cohort
                ku = (self._kappa * v[:, _I["favd"]] * favd[shape])[:, None]
                a = np.maximum(1 - c + c * self._s_lo[k], 1e-12)  # (n, J)
                b = 1 - c + c * self._s_hi[k]
                f1 = g_h[:, None, :] * exp_grid(-ku * (b - a), lo, step, nh)
                f2 = g_h[:, None, :] * exp_grid(-ku * b, lo, step, nh)
                q0, q1, q2 = (TailTable(f, step) for f in (g_h, f1, f2))
                pos_b = grid_position(z[:, None, :] / b[:, :, None], lo[:, None, None], inv, nh)
                pos_a = grid_position(z[:, None, :] / a[:, :, None], lo[:, None, None], inv, nh)
                j_rows = (np.arange(n * b.shape[1]) * nh).reshape(n, -1)[:, :, None]
                term = q0.at(rows, *pos_b) - q1.at(j_rows, *pos_a)
                if uniform:
                    grow = exp_grid(
                        np.broadcast_to(ku, b.shape), z[:, 0], z[:, 1] - z[:, 0], z.shape[1]
                    )
                else:
                    grow = np.exp(ku[:, :, None] * z[:, None, :])
                term -= grow * (q2.at(j_rows, *pos_b) - q2.at(j_rows, *pos_a))
                depth += np.einsum("j,nje->ne", self._weights[k], term)
        return depth
