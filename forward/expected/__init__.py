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
:func:`forward.expected.tables.radial_rule`) and the cohort/shape height density f_s(h),

    λ E[∫(1 − e^{−κuℓ}) dA] = Σ_s Σ_j w_j ∫ g_s(h) · φ_j(z, h) dh,  g_s = λ π Rc(h)² f_s(h),

    φ_j = 0                                 for h < z/b_j   (crown top below z)
        = 1 − exp(−κu (b_j h − z))          for z/b_j ≤ h < z/a_j
        = 1 − exp(−κu (b_j − a_j) h)         for h ≥ z/a_j   (whole chord above z).

So the height integral is exact given tail integrals on a height grid. With the
discounted tail S(t; r) = ∫_t^∞ g(h) e^{−r(h−t)} dh, r_b = κu b_j and r_d = κu(b_j − a_j),

    ∫ g φ_j dh = A_j(z/b_j) + B_j(z/a_j),
    A_j(t) = Q0(t) − S(t; r_b),   B_j(t) = e^{−r_d t} [S(t; r_b) − S(t; r_d)],

two smooth functions of one height each. A call tabulates A_j, B_j and their exact slopes
per parameter vector and cohort on ``height_nodes`` points spanning the cohort's height
distribution (fourth-order cell rule, :mod:`forward.expected.tables`), continues them
exactly below the grid and reads them by cubic Hermite interpolation
(:mod:`forward.expected.depth`): compiled or with numpy, the same numbers to rounding.

Waveform. With ``depth_nodes`` set, E[P] is evaluated on a grid of whole fine layers
(about ``depth_nodes`` points up to the template's tallest tree) starting on the bin edge
at or below each row's ground g; Catmull–Rom interpolation to the layer edges, the layer
returns ρv·ΔE[P] and the layer kernel of the explicit engine
(:func:`forward.pulse.layer_kernel`) are then one constant matrix, and each row is
shifted by whole bins (:mod:`forward.expected.grid`). With ``depth_nodes=None``, or an
understory, E[P] is evaluated at every fine-layer edge (z = edge − g) and convolved as one
matrix product. The uniform
understory multiplies E[P] by its own transmission; the ground pulse is ρg·E[P(0)]·Δz·
pulse(z_j − g), for a Gaussian or a measured pulse alike (:mod:`forward.expected.ground`).
Slopes are not modelled here.

Conditioning on the tallest tree. ``height_cap`` H stops each cohort at H: its trees below
keep their intensity, λ·f(h) for h ≤ H, so a cohort holds λ·F(H) stems on a grid ending
at H. ``apex_density`` adds that many stems per hectare, in cohort 1's shape mix, all of
height H: their depth is the closed form Σ_j w_j·λ_H·π·Rc(H)²·(1 − e^{−κu_j·c_j(z)}),
c_j(z) the chord of node j above z (:mod:`forward.expected.cohorts`). Together they give
the expected waveform of a footprint whose tallest tree is known, e.g. a latent tallest
stem in the inversion; both are checked against the mean of explicit stands.

Modules, one process each, every numpy path beside its compiled kernel under one name
and one ``backend=`` switch (:mod:`forward.backends`): :mod:`.vectors` (the parameter
vector), :mod:`.cohorts` (the trees integrated over), :mod:`.tables` (grid tables and
quadratures), :mod:`.depth` (the trees' optical depth), :mod:`.grid` (assembly of the
canopy samples), :mod:`.ground` (the ground's return) and :mod:`.model` (the model that
runs them, :class:`ExpectedWaveformModel`); :mod:`.settings` holds the numerical settings.

References
----------
Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE Trans.
Geosci. Remote Sens.* 38(6), 2617–2626.
Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
Applications*, 3rd ed., Wiley, Sec. 2.4 (the probability generating functional).
"""

from .model import ExpectedWaveformModel
from .settings import CONVERGED, NUMERICS_REVISION, ExpectedWaveforms, ModelSettings
from .vectors import (
    CONDITIONING_FIELDS,
    DEFAULT_FREE,
    FIELD_INDEX,
    MIX_FIELDS,
    VECTOR_FIELDS,
    params_from_vector,
    physical_rows,
    vectors_by_name,
)

__all__ = [
    "CONDITIONING_FIELDS",
    "CONVERGED",
    "DEFAULT_FREE",
    "FIELD_INDEX",
    "MIX_FIELDS",
    "NUMERICS_REVISION",
    "VECTOR_FIELDS",
    "ExpectedWaveformModel",
    "ExpectedWaveforms",
    "ModelSettings",
    "params_from_vector",
    "physical_rows",
    "vectors_by_name",
]
