"""Numerical building blocks of :mod:`forward.expected`.

The disc quadrature per crown shape, the tail-integral tables over tree height (fourth
order: four-point cell rule and cubic Hermite reads), exponentials on uniform grids by
cumulative products, and Catmull–Rom interpolation on uniform grids. All are vectorised
over a batch of rows.
"""

import numpy as np
from numpy.polynomial.legendre import leggauss

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


def radial_rule(shape, nodes):
    """Nodes ρ and area weights (summing to 1) of the disc quadrature for ``shape``.

    ``nodes`` is the count for cones; other shapes use :data:`RADIAL_NODES` of it.
    """
    x, w = leggauss(RADIAL_NODES.get(shape, lambda n: n)(nodes))
    x, w = 0.5 * (x + 1.0), 0.5 * w
    variable = RADIAL_VARIABLE.get(shape, "rho")
    if variable == "rho":
        return x, 2.0 * x * w  # d(ρ²) = 2ρ dρ
    if variable == "rho2":
        return np.sqrt(x), w  # area-uniform
    return np.sqrt(1.0 - x * x), 2.0 * x * w  # ρ² = 1 − u², d(ρ²) = −2u du


class TailTable:
    """Tail integral Q(t) = ∫_t^{h_last} f dh of samples f on a uniform grid (per row).

    Cells are integrated by the four-point rule δ/24·(−f₋₁ + 13f₀ + 13f₁ − f₂) (fourth
    order; the ghost values beyond the grid ends are quadratic extrapolations, so a
    density that jumps at a grid end costs nothing), and Q is read between nodes by cubic
    Hermite interpolation with the exact slopes Q' = −f.
    """

    def __init__(self, f, step):
        padded = np.empty((*f.shape[:-1], f.shape[-1] + 2))
        padded[..., 1:-1] = f
        if f.shape[-1] >= 3:
            padded[..., 0] = 3 * f[..., 0] - 3 * f[..., 1] + f[..., 2]
            padded[..., -1] = 3 * f[..., -1] - 3 * f[..., -2] + f[..., -3]
        else:
            padded[..., 0] = padded[..., -1] = 0.0
        cell = 13.0 * (padded[..., 1:-2] + padded[..., 2:-1])
        cell -= padded[..., :-3] + padded[..., 3:]
        scale = (step / 24.0).reshape((-1,) + (1,) * (f.ndim - 1))
        q = np.zeros(f.shape)
        q[..., :-1] = np.cumsum(cell[..., ::-1], axis=-1)[..., ::-1]
        q *= scale
        self.q = q
        self._flat_q = q.ravel()
        self._flat_d = (f * (24.0 * scale)).ravel()  # −dQ/dk per grid step
        self.nodes = q.shape[-1]

    def at(self, rows, i, t):
        """Q at cell ``i`` and fraction ``t`` of rows starting at flat node ``rows``."""
        idx = rows + i
        q0, q1 = self._flat_q[idx], self._flat_q[idx + 1]
        d0, d1 = self._flat_d[idx], self._flat_d[idx + 1]
        # cubic Hermite with values q0, q1 and slopes −d0, −d1 (per grid step)
        delta = q1 - q0
        return q0 - t * (d0 - t * (3 * delta + 2 * d0 + d1 - t * (2 * delta + d0 + d1)))


def exp_grid(rate, start, step, count):
    """exp(rate·(start + k·step)) for k < count, shape (*rate.shape, count).

    ``rate`` is (n, p) and ``start``, ``step`` are (n,): one exponential per (row, p) and
    a cumulative product along the grid (much cheaper than an exponential per point).
    """
    ratio = np.exp(rate * step[:, None])
    out = np.empty((*rate.shape, count))
    out[..., 0] = np.exp(rate * start[:, None])
    out[..., 1:] = ratio[..., None]
    return np.cumprod(out, axis=-1, out=out)


def grid_position(x, lo, inv, nh):
    p = np.clip((x - lo) * inv, 0.0, nh - 1.0)
    i = np.minimum(p.astype(np.intp), nh - 2)
    return i, p - i


def catmull_rom(values, z, step, beyond=0.0):
    """Catmull–Rom interpolation of ``values`` (n, m) on grids 0, step, … at z (n, e).

    Beyond the last node the values are taken as ``beyond`` (no crown above the tallest
    tree: zero depth, unit gap).
    """
    n, m = values.shape
    y = np.full((n, m + 3), float(beyond))
    y[:, 1 : m + 1] = values
    y[:, 0] = 2 * values[:, 0] - values[:, 1]  # linear extrapolation below z = 0
    y0, y1, y2, y3 = y[:, :-3], y[:, 1:-2], y[:, 2:-1], y[:, 3:]
    coef = np.empty((n, m, 4))
    coef[..., 0] = y1
    coef[..., 1] = 0.5 * (y2 - y0)
    coef[..., 2] = y0 - 2.5 * y1 + 2 * y2 - 0.5 * y3
    coef[..., 3] = 0.5 * (y3 - y0) + 1.5 * (y1 - y2)
    p = np.clip(z / step[:, None], 0.0, m - 1.0)
    i = p.astype(np.intp)
    t = p - i
    c = coef.reshape(-1, 4)[(np.arange(n) * m)[:, None] + i]
    return c[..., 0] + t * (c[..., 1] + t * (c[..., 2] + t * c[..., 3]))
