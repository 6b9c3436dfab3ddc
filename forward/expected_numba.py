"""Compiled tree optical depth of :mod:`forward.expected` (optional, needs numba).

The same quantity as the numpy path of
:meth:`forward.expected.ExpectedWaveformModel._tree_depth`, computed row by row: the
discounted tails S(h_i; r) by their backward recurrence S_i = e^{−rδ}·S_{i+1} + C_i (C_i
the fourth-order cell rule of :func:`forward.expected_tables.tail_matrix` applied to
g(h)·e^{−r(h − h_i)}), the tables A_j, B_j with their exact slopes, and cubic Hermite
reads at z/b_j and z/a_j, with the exact continuation below the grid. It agrees with the
numpy path to rounding. :data:`AVAILABLE` is False when numba cannot be imported.
"""

import importlib.util

import numpy as np

from .expected_tables import LAGRANGE_CUBIC, MAX_EXPONENT, WEIGHT_SERIES

#: Whether numba is installed (it is imported, and the kernel compiled, on first use).
AVAILABLE = importlib.util.find_spec("numba") is not None

__all__ = ["AVAILABLE", "add_tree_depth"]


def _discounted(g, rate, step, out):
    """Discounted tails of samples ``g`` (nodes ≥ 4) at ``rate`` (1/m) into ``out``.

    Cells by the exponentially fitted rule of :func:`forward.expected_tables.cell_weights`
    (Taylor series below x = 0.5, moments by recurrence above), then the backward recurrence.
    """
    nodes = g.size
    x = rate * step
    w = np.empty(4)
    if x < 0.5:
        for m in range(4):
            acc = WEIGHT_SERIES[m, -1]
            for k in range(WEIGHT_SERIES.shape[1] - 2, -1, -1):
                acc = acc * x + WEIGHT_SERIES[m, k]
            w[m] = acc
    else:
        e = np.exp(-x)
        moments = np.empty(4)
        moments[0] = -np.expm1(-x) / x
        for n in range(1, 4):
            moments[n] = (n * moments[n - 1] - e) / x
        w[:] = LAGRANGE_CUBIC @ moments
    rho = np.exp(-x)
    out[nodes - 1] = 0.0
    for i in range(nodes - 2, -1, -1):
        before = g[i - 1] if i > 0 else 3.0 * g[0] - 3.0 * g[1] + g[2]
        after = g[i + 2] if i < nodes - 2 else 3.0 * g[i + 1] - 3.0 * g[i] + g[i - 1]
        cell = w[0] * before + w[1] * g[i] + w[2] * g[i + 1] + w[3] * after
        out[i] = rho * out[i + 1] + step * cell


def _hermite(values, slopes, p):
    """Cubic Hermite read of a table at grid position 0 ≤ p ≤ nodes − 1."""
    i = min(int(p), values.size - 2)
    t = p - i
    y0, d0, d1 = values[i], slopes[i], slopes[i + 1]
    rise = values[i + 1] - y0
    return y0 + t * (d0 + t * (3.0 * rise - 2.0 * d0 - d1 + t * (d0 + d1 - 2.0 * rise)))


def _add_tree_depth(g, lo, step, a, b, ku, w, z, depth):
    """Add Σ_j w_j [A_j(z/b_j) + B_j(z/a_j)] of one cohort to ``depth`` (n, e)."""
    n, nodes = g.shape
    n_nodes = a.shape[1]
    q0 = np.empty(nodes)
    s_b = np.empty(nodes)
    s_d = np.empty(nodes)
    a_val = np.empty(nodes)
    a_slope = np.empty(nodes)
    b_val = np.empty(nodes)
    b_slope = np.empty(nodes)
    for r in range(n):
        h_step = step[r]
        cap = MAX_EXPONENT / max(h_step * (nodes - 1), 1e-300)
        _discounted(g[r], 0.0, h_step, q0)
        for j in range(n_nodes):
            weight = w[r, j]
            if weight == 0.0:
                continue
            r_b = min(ku[r, j] * b[r, j], cap)
            r_d = min(ku[r, j] * (b[r, j] - a[r, j]), cap)
            _discounted(g[r], r_b, h_step, s_b)
            _discounted(g[r], r_d, h_step, s_d)
            decay = np.exp(-r_d * lo[r])
            ratio = np.exp(-r_d * h_step)
            for i in range(nodes):
                a_val[i] = q0[i] - s_b[i]
                a_slope[i] = -r_b * s_b[i] * h_step
                b_val[i] = decay * (s_b[i] - s_d[i])
                b_slope[i] = (-r_d * b_val[i] + decay * (r_b * s_b[i] - r_d * s_d[i])) * h_step
                decay *= ratio
            below_d = np.exp(-r_d * lo[r])
            b_lo, a_lo = b[r, j] * lo[r], a[r, j] * lo[r]
            inv_b, inv_a = 1.0 / (b[r, j] * h_step), 1.0 / (a[r, j] * h_step)
            start, last = lo[r] / h_step, nodes - 1.0
            for k in range(z.shape[1]):
                zk = z[r, k]
                # A_j at t = z/b_j; below the grid A(t) = A(lo) + S_b(lo)(1 − e^{−κu(b·lo − z)})
                p = zk * inv_b - start
                if zk < b_lo:
                    total = a_val[0] - s_b[0] * np.expm1(-ku[r, j] * (b_lo - zk))
                elif p < last:  # zero from the top of the grid up
                    total = _hermite(a_val, a_slope, p)
                else:
                    continue  # z/a_j ≥ z/b_j is beyond the grid too
                # B_j at t = z/a_j; below the grid B(t) = B(lo) + S_b(lo)(e^{−κu(b·lo − z)}
                # − e^{−r_d·lo})
                p = zk * inv_a - start
                if zk < a_lo:
                    total += b_val[0] + s_b[0] * (np.exp(-ku[r, j] * (b_lo - zk)) - below_d)
                elif p < last:
                    total += _hermite(b_val, b_slope, p)
                depth[r, k] += weight * total


_COMPILED = []


def _kernel():
    """The compiled kernel: the helpers are compiled first, so that it calls them."""
    if not _COMPILED:
        from numba import njit

        global _discounted, _hermite
        _discounted = njit(cache=True)(_discounted)
        _hermite = njit(cache=True)(_hermite)
        _COMPILED.append(njit(cache=True)(_add_tree_depth))
    return _COMPILED[0]


def _as_kernel_array(x, shape):
    """``x`` as a C-contiguous float64 array of ``shape`` (no copy if it already is one)."""
    if (
        isinstance(x, np.ndarray)
        and x.shape == shape
        and x.dtype == np.float64
        and x.flags.c_contiguous
    ):
        return x
    return np.ascontiguousarray(np.broadcast_to(x, shape), dtype=np.float64)


def add_tree_depth(g, lo, step, a, b, ku, w, z, depth):
    """Compiled twin of :func:`forward.expected_depth.add_tree_depth`: the same arguments
    (less the numpy path's table options) and the same result, ``depth`` updated in place.
    """
    n, n_nodes = g.shape[0], np.shape(a)[-1]
    shapes = [g.shape, (n,), (n,), *[(n, n_nodes)] * 4, depth.shape]
    arrays = [_as_kernel_array(x, shape) for x, shape in zip((g, lo, step, a, b, ku, w, z), shapes)]
    _kernel()(*arrays, depth)
