"""Tree optical depth of :mod:`forward.expected` with numpy (the path without numba).

Per cohort, every radial node j contributes w_j·[A_j(z/b_j) + B_j(z/a_j)] (see
:meth:`forward.expected.ExpectedWaveformModel._tree_depth`). The tables of all nodes are
built at once, (rows, nodes, height grid), by :func:`forward.expected_tables.discounted_tails`;
nodes that are read at the same place (every node of a cone, cylinder or hemi-ellipsoid
shares a(ρ) = 1 − c) are summed first, and every read is a cubic Hermite interpolation.
:mod:`forward.expected_numba` computes the same numbers row by row.
"""

import numpy as np

from .expected_tables import discounted_tails, hermite_read, tail_integrals


def add_point_depth(g, height, a, b, ku, w, z, depth):
    """Add the depth of stems all of one height H per row to ``depth`` (n, e) in place:
    Σ_j w_j·g·(1 − exp(−κu_j·max(0, b_j H − max(z, a_j H)))), the chord of node j above z.

    ``g`` (n,) is λ·π·Rc(H)² (stems/m² times crown area, m²/m²), ``height`` H (n,) (m);
    ``a``, ``b``, ``ku``, ``w`` and ``z`` as in :func:`add_tree_depth`.
    """
    top = (b * height[:, None])[:, :, None]
    bottom = (a * height[:, None])[:, :, None]
    chord = np.clip(top - np.maximum(z[:, None, :], bottom), 0.0, None)
    intercepted = -np.expm1(-ku[:, :, None] * chord)
    depth += g[:, None] * np.einsum("nj,nje->ne", w, intercepted)


def groups(values):
    """(G, J) indicator of equal values (G distinct), or None when all differ."""
    unique, inverse = np.unique(np.round(values, 12), return_inverse=True)
    if unique.size == values.size:
        return None
    return (inverse[None, :] == np.arange(unique.size)[:, None]).astype(float)


def add_tree_depth(g, lo, step, a, b, ku, w, z, depth, tails=None, a_groups=None, b_groups=None):
    """Add one cohort's Σ_j w_j [A_j(z/b_j) + B_j(z/a_j)] to ``depth`` (n, e) in place.

    Parameters
    ----------
    g : array (n, nodes)
        λ·π·Rc(h)²·f(h) of the cohort on its height grid (1/m).
    lo, step : array (n,) (m)
        Grid start and step.
    a, b : array (n, J)
        Crown interval ends over tree height per radial node.
    ku : array (n, J) (1/m)
        κ·u per node.
    w : array (n, J) or (1, J)
        Quadrature weight × shape fraction per node.
    z : array (n, e) (m)
        Heights above the ground, ≥ 0.
    depth : array (n, e)
        Accumulator of the tree optical depth.
    tails : array (nodes, nodes) or None
        :func:`forward.expected_tables.tail_matrix` of the grid, or None.
    a_groups, b_groups : array (G, J) or None
        :func:`groups` of the nodes' s_lo and s_hi.
    """

    n, nh = g.shape
    n_nodes = a.shape[1]
    rates = np.concatenate([ku * b, ku * (b - a)], axis=1)
    s, r, decay = discounted_tails(g, rates, step, tails)
    q0 = step[:, None] * tail_integrals(g, tails)
    s_b, s_d = s[:, :n_nodes], s[:, n_nodes:]
    r_b, r_d = r[:, :n_nodes, None], r[:, n_nodes:, None]
    wide = w[:, :, None]
    # A_j and its slope per grid step, weighted
    a_val = (q0[:, None, :] - s_b) * wide
    a_slope = (-r_b * step[:, None, None]) * s_b * wide
    # B_j: e^{−r_d h} = e^{−r_d lo}·decay_d
    e_d = decay[:, n_nodes:] * (np.exp(-r_d[..., 0] * lo[:, None]) * w)[:, :, None]
    b_val = e_d * (s_b - s_d)
    b_slope = (r_b * s_b - r_d * s_d) * e_d - r_d * b_val
    b_slope *= step[:, None, None]
    inv_step = (1.0 / step)[:, None]
    for val, slope, group, ends in (
        (a_val, a_slope, b_groups, b),
        (b_val, b_slope, a_groups, a),
    ):
        if group is not None:  # (G, J) indicator: sum nodes read at one place
            val, slope = group @ val, group @ slope
            ends = ends[:, np.argmax(group, axis=1)]
        rows = (np.arange(n * ends.shape[1]) * nh).reshape(n, -1, 1)
        pos = z[:, None, :] * (inv_step / ends)[:, :, None]
        pos -= (lo * inv_step[:, 0])[:, None, None]
        read = hermite_read(val.ravel(), slope.ravel(), rows, pos, nh)
        depth += read.sum(axis=1)
    # below the grid (t < lo) both tables were read at lo; the exact difference is
    # w·S_b(lo)·(1 − e^{−κu(b·lo − max(z, a·lo))}) for z < b·lo, else 0
    top = b * lo[:, None]
    cols = int(np.max(np.sum(z < top.max(axis=1)[:, None], axis=1)))
    if cols:
        zz = z[:, None, :cols]
        x = np.maximum(zz, (a * lo[:, None])[:, :, None])
        np.subtract(top[:, :, None], x, out=x)
        np.maximum(x, 0.0, out=x)
        x *= -ku[:, :, None]
        corr = -np.expm1(x, out=x)
        corr *= (w * s_b[:, :, 0])[:, :, None]
        depth[:, :cols] += corr.sum(axis=1)
