"""Numerical building blocks of :mod:`forward.expected`: the grid tables.

The disc quadrature per crown shape, tail integrals over tree height as one matrix
product (a fourth-order cell rule), discounted tails and cubic Hermite reads of tabulated
functions. All are vectorised over a batch of rows and use float64 throughout
(Catmull–Rom interpolation of the depth grid and the grid operator are in
:mod:`.interpolation`).
Beside them, their scalar twins for the compiled kernels of :mod:`.depth`
(:func:`cell_weights_at`, :func:`discounted_tail_row`, :func:`hermite_at`), the same
arithmetic one row at a time.
"""

import math

import numpy as np
from numpy.polynomial.legendre import leggauss

from ..backends import jit

#: Radial variable of the disc quadrature per shape: ``rho`` (Gauss–Legendre in r/Rc,
#: smooth for chords linear in ρ) or ``chord`` (in u = sqrt(1 − ρ²), which makes the
#: spheroid chords linear and removes their square-root edge singularity).
RADIAL_VARIABLE = {
    "cone": "rho",
    "cylinder": "rho",
    "ellipsoid": "chord",
    "hemi-ellipsoid": "chord",
}


#: Radial nodes per shape as a function of the requested count: the chord of a cylinder is
#: constant (one node is exact) and the full spheroid's chord, linear in u, converges about
#: two nodes faster than cones (measured against 48 nodes; see the runtime study).
RADIAL_NODES = {
    "cone": lambda n: n,
    "cylinder": lambda n: 1,
    "ellipsoid": lambda n: max(2, n - 2),
    "hemi-ellipsoid": lambda n: n,
}

#: Largest exponent (rate × grid span) used by :func:`discounted_tails`; larger rates are
#: capped there (crowns that opaque return the same as any larger rate, to rounding).
MAX_EXPONENT = 600.0


def radial_rule(shape, nodes):
    """Nodes and area weights of the disc quadrature for a crown shape.

    Parameters
    ----------
    shape : str
        A crown shape (:data:`forward.crowns.CROWN_SHAPES`).
    nodes : int
        The count for cones; other shapes use :data:`RADIAL_NODES` of it.

    Returns
    -------
    rho : array
        Nodes ρ = r/Rc.
    weights : array
        Area weights, summing to 1.

    Notes
    -----
    Gauss–Legendre in ρ for cones and cylinders, in u = sqrt(1 − ρ²) for spheroids
    (:data:`RADIAL_VARIABLE`); the area element is dA = π Rc² d(ρ²).
    """
    x, w = leggauss(RADIAL_NODES.get(shape, lambda n: n)(nodes))
    x, w = 0.5 * (x + 1.0), 0.5 * w
    if RADIAL_VARIABLE.get(shape, "rho") == "rho":
        return x, 2.0 * x * w  # d(ρ²) = 2ρ dρ
    return np.sqrt(1.0 - x * x), 2.0 * x * w  # ρ² = 1 − u², d(ρ²) = −2u du


def _cell_rule(padded):
    """Four-point cell integrals (per unit step) of values padded by one ghost each side."""
    cell = 13.0 * (padded[..., 1:-2] + padded[..., 2:-1]) - padded[..., :-3] - padded[..., 3:]
    return cell / 24.0


def _with_ghosts(f):
    """``f`` padded by quadratic extrapolations (zeros when it has fewer than 3 nodes)."""
    padded = np.zeros((*f.shape[:-1], f.shape[-1] + 2))
    padded[..., 1:-1] = f
    if f.shape[-1] >= 3:
        padded[..., 0] = 3 * f[..., 0] - 3 * f[..., 1] + f[..., 2]
        padded[..., -1] = 3 * f[..., -1] - 3 * f[..., -2] + f[..., -3]
    return padded


def tail_integrals(f, matrix=None):
    """Tail integrals per unit step of samples on a uniform grid.

    Parameters
    ----------
    f : array (..., nodes)
    matrix : array (nodes, nodes), optional
        :func:`tail_matrix` of the grid: one matrix product (fastest on short grids);
        without, a cumulative sum.

    Returns
    -------
    array (..., nodes)
        Q[i] = ∫_{h_i}^{h_last} f dh / step.

    Notes
    -----
    Each cell is integrated by the four-point rule δ/24·(−f₋₁ + 13f₀ + 13f₁ − f₂) (fourth
    order); the ghost values beyond the grid ends are quadratic extrapolations, so a
    density that jumps at a grid end costs nothing.
    """
    if matrix is not None:
        return f @ matrix
    q = np.zeros(f.shape)
    q[..., :-1] = np.cumsum(_cell_rule(_with_ghosts(f))[..., ::-1], axis=-1)[..., ::-1]
    return q


def tail_matrix(nodes):
    """The matrix T (nodes, nodes) with ``f @ T`` = :func:`tail_integrals` of f.

    Parameters
    ----------
    nodes : int

    Returns
    -------
    array (nodes, nodes)
        Every step of the rule is linear in f.
    """
    return tail_integrals(np.eye(nodes))


def decay_grid(rate, step, count):
    """exp(−rate·k·step) for k < count, by repeated squaring.

    Parameters
    ----------
    rate : array (n, p) (1/m)
    step : array (n,) (m)
    count : int

    Returns
    -------
    array (n, p, count)
        Only log2(count) multiplications of growing slices, no exponential per grid point.
    """
    out = np.empty((*rate.shape, count))
    out[..., 0] = 1.0
    if count > 1:
        factor = np.exp(-rate * step[:, None])[..., None]
        filled = 1
        while filled < count:
            take = min(filled, count - filled)
            np.multiply(out[..., :take], factor, out=out[..., filled : filled + take])
            filled += take
            factor = factor * factor
    return out


#: Monomial coefficients (powers 0…3) of the cubic Lagrange basis on s = −1, 0, 1, 2.
LAGRANGE_CUBIC = (
    np.array(
        [
            [0.0, -2.0, 3.0, -1.0],
            [6.0, -3.0, -6.0, 3.0],
            [0.0, 6.0, 3.0, -3.0],
            [0.0, -1.0, 0.0, 1.0],
        ]
    )
    / 6.0
)

#: Taylor coefficients in x of :func:`cell_weights` (4 weights × 14 powers), for x < 0.5:
#: the moments ∫_0^1 s^n e^{−xs} ds = Σ_k (−x)^k / (k!·(n + k + 1)), through the basis.
WEIGHT_SERIES = LAGRANGE_CUBIC @ np.array(
    [[(-1.0) ** k / (math.factorial(k) * (n + k + 1)) for k in range(14)] for n in range(4)]
)


def cell_weights(x):
    """Weights of an exponentially fitted four-point cell rule.

    Parameters
    ----------
    x : float or array
        rate × step ≥ 0.

    Returns
    -------
    array (..., 4)
        Weights of g(−1), g(0), g(1), g(2) in ∫_0^1 g(s)·e^{−x s} ds, g cubic.

    Notes
    -----
    The exponential is integrated exactly against the cubic through the four values: at
    x = 0 the weights are (−1, 13, 13, −1)/24, and they stay bounded for any x ≥ 0, where
    the plain rule applied to g·e^{−xs} blows up once x ≫ 1. Below x = 0.5 the weights
    are their Taylor series (:data:`WEIGHT_SERIES`); above, the moments follow the
    recurrence M_n = (n·M_{n−1} − e^{−x})/x.
    """
    x = np.asarray(x, float)[..., None]
    series = np.full((*x.shape[:-1], 4), WEIGHT_SERIES[:, -1])
    for k in range(WEIGHT_SERIES.shape[1] - 2, -1, -1):
        series *= x
        series += WEIGHT_SERIES[:, k]
    xl = np.maximum(x, 0.5)
    e = np.exp(-xl)
    moments = [-np.expm1(-xl) / xl]
    for n in range(1, 4):
        moments.append((n * moments[-1] - e) / xl)
    recurrence = np.concatenate(moments, axis=-1) @ LAGRANGE_CUBIC.T
    return np.where(x < 0.5, series, recurrence)


@jit
def _series(m, x):
    """Row ``m`` of the cell weights' Taylor series at x (Horner's rule)."""
    acc = WEIGHT_SERIES[m, -1]
    for k in range(WEIGHT_SERIES.shape[1] - 2, -1, -1):
        acc = acc * x + WEIGHT_SERIES[m, k]
    return acc


@jit
def cell_weights_at(x):
    """:func:`cell_weights` at one x, as four scalars (the kernels' twin).

    Parameters
    ----------
    x : float
        rate × step ≥ 0.

    Returns
    -------
    (float, float, float, float)
        Taylor series below x = 0.5, moments by recurrence above.
    """
    if x < 0.5:
        return _series(0, x), _series(1, x), _series(2, x), _series(3, x)
    e = np.exp(-x)
    m0 = -np.expm1(-x) / x
    m1 = (m0 - e) / x
    m2 = (2.0 * m1 - e) / x
    m3 = (3.0 * m2 - e) / x
    c = LAGRANGE_CUBIC
    return (
        c[0, 0] * m0 + c[0, 1] * m1 + c[0, 2] * m2 + c[0, 3] * m3,
        c[1, 0] * m0 + c[1, 1] * m1 + c[1, 2] * m2 + c[1, 3] * m3,
        c[2, 0] * m0 + c[2, 1] * m1 + c[2, 2] * m2 + c[2, 3] * m3,
        c[3, 0] * m0 + c[3, 1] * m1 + c[3, 2] * m2 + c[3, 3] * m3,
    )


def discounted_tails(g, rate, step, tails=None):
    """S(h_i) = ∫_{h_i}^{h_last} g(h)·exp(−rate·(h − h_i)) dh on a uniform grid.

    Each cell is integrated by :func:`cell_weights` (the cubic through four samples of g,
    times the exact exponential; ghost samples beyond the grid ends are quadratic
    extrapolations), and S_i = Σ_{m ≥ i} e^{−rate·(h_m − h_i)}·C_m.

    Parameters
    ----------
    g : array (n, nodes)
        Samples of the integrand's density on each row's grid.
    rate : array (n, p) (1/m)
        Decay rates, non-negative; capped so that rate × span ≤ :data:`MAX_EXPONENT`.
    step : array (n,) (m)
        Grid steps.
    tails : array or None
        Not None on short grids: the sums are then a matrix product.

    Returns
    -------
    S : array (n, p, nodes)
    rate : array (n, p)
        The rates used (after the cap).
    decay : array (n, p, nodes)
        exp(−rate·(h − h_0)).
    """
    nodes = g.shape[-1]
    span = step * (nodes - 1)
    rate = np.minimum(rate, (MAX_EXPONENT / np.maximum(span, 1e-300))[:, None])
    weights = cell_weights(rate * step[:, None])[..., None, :]  # (n, p, 1, 4)
    padded = _with_ghosts(g)[:, None, :]
    cells = weights[..., 0] * padded[..., : nodes - 1]
    for k in range(1, 4):
        cells += weights[..., k] * padded[..., k : nodes - 1 + k]
    decay = decay_grid(rate, step, nodes)
    cells *= decay[..., :-1]
    s = np.zeros(decay.shape)
    if tails is not None:
        s[..., :-1] = cells @ np.triu(np.ones((nodes - 1, nodes - 1))).T
    else:
        s[..., :-1] = np.cumsum(cells[..., ::-1], axis=-1)[..., ::-1]
    s *= step[:, None, None]
    s /= decay
    return s, rate, decay


@jit
def discounted_tail_row(g, rate, step, out):
    """:func:`discounted_tails` of one row at one rate, into ``out`` (the kernels' twin).

    Parameters
    ----------
    g : array (nodes ≥ 4,)
    rate : float (1/m)
        Already capped (:data:`MAX_EXPONENT`).
    step : float (m)
    out : array (nodes,)
        Overwritten with S_i.

    Notes
    -----
    Cells by :func:`cell_weights_at`, then the backward recurrence
    S_i = e^{−rate·step}·S_{i+1} + C_i.
    """
    nodes = g.size
    x = rate * step
    w0, w1, w2, w3 = cell_weights_at(x)
    rho = np.exp(-x)
    out[nodes - 1] = 0.0
    for i in range(nodes - 2, -1, -1):
        before = g[i - 1] if i > 0 else 3.0 * g[0] - 3.0 * g[1] + g[2]
        after = g[i + 2] if i < nodes - 2 else 3.0 * g[i + 1] - 3.0 * g[i] + g[i - 1]
        cell = w0 * before + w1 * g[i] + w2 * g[i + 1] + w3 * after
        out[i] = rho * out[i + 1] + step * cell


def hermite_read(values, slopes, rows, position, nodes):
    """Read tabulated functions at fractional grid positions by cubic Hermite interpolation.

    Parameters
    ----------
    values, slopes : array
        Flat tables (rows of ``nodes`` values) and their slopes per grid step.
    rows : int array, broadcastable to ``position``
        Flat index of each read's table row.
    position : array
        Grid positions (0 = first node); clipped to the grid. Overwritten.
    nodes : int

    Returns
    -------
    array
        y0 + t·d0 + t²·(3Δ − 2d0 − d1) + t³·(d0 + d1 − 2Δ) in each read's cell.
    """
    np.clip(position, 0.0, nodes - 1.0, out=position)
    i = position.astype(np.intp)
    np.minimum(i, nodes - 2, out=i)
    position -= i
    i += rows
    y0, y1 = values[i], values[i + 1]
    d0, d1 = slopes[i], slopes[i + 1]
    y1 -= y0  # the rise over the cell
    t = position
    # y0 + t·d0 + t²·(3Δ − 2d0 − d1) + t³·(d0 + d1 − 2Δ)
    d1 += d0
    cubic = d1 - 2.0 * y1
    cubic *= t
    cubic += 3.0 * y1 - d0 - d1
    cubic *= t
    cubic += d0
    cubic *= t
    cubic += y0
    return cubic


@jit
def hermite_at(values, slopes, p):
    """:func:`hermite_read` of one table at one position (the kernels' twin).

    Parameters
    ----------
    values, slopes : array (nodes,)
    p : float
        Grid position, 0 ≤ p ≤ nodes − 1.

    Returns
    -------
    float
    """
    i = min(int(p), values.size - 2)
    t = p - i
    y0, d0, d1 = values[i], slopes[i], slopes[i + 1]
    rise = values[i + 1] - y0
    return y0 + t * (d0 + t * (3.0 * rise - 2.0 * d0 - d1 + t * (d0 + d1 - 2.0 * rise)))
