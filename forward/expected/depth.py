r"""The trees' optical depth of the expected waveform, with numpy and compiled.

At heights z above the ground, the trees' optical depth is λ·E[∫(1 − e^{−κuℓ}) dA]
(:mod:`forward.expected`), a sum over cohorts and over the radial nodes j of the crown
disc. With the cohort's crown-area density g(h) = λ·π·Rc(h)²·f(h) on its height grid,
node j contributes w_j·[A_j(z/b_j) + B_j(z/a_j)]: two functions of one height t each,

    A_j(t) = Q0(t) − S_j(t; κu b_j),
    B_j(t) = e^{−κu(b_j − a_j) t} [S_j(t; κu b_j) − S_j(t; κu(b_j − a_j))],

where S(t; r) = ∫_t^∞ g(h) e^{−r(h − t)} dh is a discounted tail and a_j, b_j the
crown's chord ends over tree height. They are tabulated with their exact slopes
(A' = −r_b S_b, B' = −r_d B + e^{−r_d t}(r_b S_b − r_d S_d)) on the height grid and read
by cubic Hermite interpolation, with the exact continuation below the grid. Stems all of
one height H (the apex of a footprint conditioned on its tallest stem) add the closed form
Σ_j w_j·λπRc(H)²·(1 − exp(−κu_j·max(0, b_j H − max(z, a_j H)))).

:func:`add_cohort_depth` and :func:`add_point_depth` take ``backend=``
(:mod:`forward.backends`): numpy builds the tables of all nodes at once, (rows, nodes,
height grid), with :func:`.tables.discounted_tails` and sums the nodes read at one place
(every node of a cone, cylinder or hemi-ellipsoid shares a(ρ) = 1 − c) before the read;
the compiled kernels compute the same numbers row by row (below every chord, z < a_j·lo,
the two continuations sum to a constant: no exponential per height).
"""

import numpy as np

from ..backends import as_float64 as _f64
from ..backends import jit, resolve
from ..crowns import crown_radius
from .tables import (
    MAX_EXPONENT,
    discounted_tail_row,
    discounted_tails,
    hermite_at,
    hermite_read,
    tail_integrals,
)

#: Stems of one height per row where a model has none: no rows, so nothing is added.
NO_POINTS = (np.zeros(0), np.zeros(0), np.zeros((0, 0)))


def chord_ends(ratio, s_lo, s_hi):
    """Crown chord ends over tree height per row and radial node.

    Parameters
    ----------
    ratio : array (n,)
        Crown length ratios c.
    s_lo, s_hi : array (J,)
        The nodes' chord ends as fractions of the crown length above its base.

    Returns
    -------
    a, b : arrays (n, J)
        a = max(1 − c + c·s_lo, 1e-12) and b = 1 − c + c·s_hi: a column at node j crosses
        a crown of height h between a·h and b·h.
    """
    c = ratio[:, None]
    return np.maximum(1.0 - c + c * s_lo, 1e-12), 1.0 - c + c * s_hi


def add_cohort_depth(
    pdf, lo, step, stems, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z, depth,
    *, backend="auto", tails=None, a_groups=None, b_groups=None,
):  # fmt: skip
    """Add one cohort's tree optical depth at heights ``z`` to ``depth`` (in place).

    Parameters
    ----------
    pdf : array (n, nodes) (1/m)
        The cohort's height density on each row's grid lo + step·i.
    lo, step : array (n,) (m)
        Grid start and step.
    stems : array (n,) (stems/ha)
        The cohort's stems.
    r0, r1 : array (n,) (m, m/m)
        Crown radius Rc = r0 + r1·h.
    ratio : array (n,)
        Crown length ratio c.
    s_lo, s_hi : array (J,)
        Each radial node's chord ends as fractions of the crown length above its base.
    extinction : array (n,) (1/m)
        κ·FAVD.
    node_favd : array (J,)
        FAVD ratio of each node's shape (κu_j = extinction·node_favd_j).
    w : array (n, J)
        Quadrature weight × shape fraction per node.
    z : array (n, e) (m)
        Heights above the ground, ≥ 0.
    depth : array (n, e)
        Accumulator of the tree optical depth.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` (:func:`forward.backends.resolve`).
    tails : array (nodes, nodes) or None
        numpy only: :func:`.tables.tail_matrix` of the grid (faster on short grids).
    a_groups, b_groups : array (G, J) or None
        numpy only: :func:`groups` of ``s_lo`` and ``s_hi``.

    Notes
    -----
    g(h) = λ·π·Rc(h)²·f(h), with f normalised on the grid by the cell rule, then
    Σ_j w_j [A_j(z/b_j) + B_j(z/a_j)] (module docstring).
    """
    if resolve(backend) == "numba":
        arrays = (pdf, lo, step, stems, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z)
        cohort_depth_kernel(*(_f64(x) for x in arrays), depth)
        return
    a, b = chord_ends(ratio, s_lo, s_hi)
    ku = extinction[:, None] * node_favd
    h = lo[:, None] + step[:, None] * np.arange(pdf.shape[1], dtype=float)
    norm = step * tail_integrals(pdf, tails)[:, 0]
    radius = crown_radius(h, r0[:, None], r1[:, None])
    scale = (np.pi / 1e4) * stems / np.where(norm > 0, norm, 1.0)
    g = scale[:, None] * radius**2 * pdf
    add_tree_depth(g, lo, step, a, b, ku, w, z, depth, tails, a_groups, b_groups)


def add_point_depth(
    stems, height, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z, depth,
    *, backend="auto",
):  # fmt: skip
    """Add the optical depth of stems all of one height H per row to ``depth`` (in place).

    Parameters
    ----------
    stems : array (n,) (stems/ha)
    height : array (n,) (m)
        H.
    r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z, depth, backend
        As in :func:`add_cohort_depth`.

    Notes
    -----
    Σ_j w_j·g·(1 − exp(−κu_j·max(0, b_j H − max(z, a_j H)))), g = λ·π·Rc(H)², the
    chord of node j above z.
    """
    if resolve(backend) == "numba":
        arrays = (stems, height, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z)
        point_depth_kernel(*(_f64(x) for x in arrays), depth)
        return
    a, b = chord_ends(ratio, s_lo, s_hi)
    ku = extinction[:, None] * node_favd
    g = (np.pi / 1e4) * stems * crown_radius(height, r0, r1) ** 2
    top = (b * height[:, None])[:, :, None]
    bottom = (a * height[:, None])[:, :, None]
    chord = np.clip(top - np.maximum(z[:, None, :], bottom), 0.0, None)
    intercepted = -np.expm1(-ku[:, :, None] * chord)
    depth += g[:, None] * np.einsum("nj,nje->ne", w, intercepted)


def tree_depth(cohorts, points, crowns, z, *, backend="auto", tables=(None, None, None)):
    """The trees' optical depth λ·E[∫(1 − e^{−κuℓ}) dA] at heights ``z`` (n, e) ≥ 0.

    Parameters
    ----------
    cohorts : list of tuple
        Per cohort with trees: (pdf (n, nodes), lo (n,), step (n,), stems (n,), w (n, J)),
        as :func:`add_cohort_depth` takes them.
    points : tuple or None
        (stems (n,), height (n,), w (n, J)) of stems of one height per row, or None.
    crowns : tuple
        (r0, r1, ratio, s_lo, s_hi, extinction, node_favd) of :func:`add_cohort_depth`.
    z : array (n, e) (m)
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"``.
    tables : tuple
        numpy only: (tails, a_groups, b_groups) of :func:`add_cohort_depth`.

    Returns
    -------
    array (n, e)
        The sum of :func:`add_cohort_depth` over ``cohorts`` and :func:`add_point_depth`
        of ``points``.

    References
    ----------
    Sun, G. & Ranson, K. J. (2000). Modeling lidar returns from forest canopies. *IEEE
    Trans. Geosci. Remote Sens.* 38(6), 2617–2626 (the crowns' optical depth along a
    column).
    Chiu, S. N., Stoyan, D., Kendall, W. S. & Mecke, J. (2013). *Stochastic Geometry and its
    Applications*, 3rd ed., Wiley, Sec. 3.1 (the Boolean model: the expected gap as the
    exponential of the mean depth).
    """
    tails, a_groups, b_groups = tables
    depth = np.zeros_like(z)
    for pdf, lo, step, stems, w in cohorts:
        add_cohort_depth(
            pdf, lo, step, stems, *crowns, w, z, depth,
            backend=backend, tails=tails, a_groups=a_groups, b_groups=b_groups,
        )  # fmt: skip
    if points is not None:
        stems, height, w = points
        add_point_depth(stems, height, *crowns, w, z, depth, backend=backend)
    return depth


def groups(values):
    """Indicator of equal values, for summing tables read at one place.

    Parameters
    ----------
    values : array (J,)

    Returns
    -------
    array (G, J) or None
        Row g marks the nodes with the g-th distinct value; None when all differ.
    """
    unique, inverse = np.unique(np.round(values, 12), return_inverse=True)
    if unique.size == values.size:
        return None
    return (inverse[None, :] == np.arange(unique.size)[:, None]).astype(float)


def add_tree_depth(g, lo, step, a, b, ku, w, z, depth, tails=None, a_groups=None, b_groups=None):
    """Add one cohort's Σ_j w_j [A_j(z/b_j) + B_j(z/a_j)] to ``depth`` (n, e) in place,
    from its crown-area density g on its height grid (the numpy path of
    :func:`add_cohort_depth`).

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
        :func:`.tables.tail_matrix` of the grid, or None.
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


#: :func:`forward.crowns.crown_radius`, compiled for the kernels.
_crown_radius = jit(crown_radius)


@jit
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
        discounted_tail_row(g[r], 0.0, h_step, q0)
        for j in range(n_nodes):
            weight = w[r, j]
            if weight == 0.0:
                continue
            r_b = min(ku[r, j] * b[r, j], cap)
            r_d = min(ku[r, j] * (b[r, j] - a[r, j]), cap)
            discounted_tail_row(g[r], r_b, h_step, s_b)
            discounted_tail_row(g[r], r_d, h_step, s_d)
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
            # below a_j·lo ≤ b_j·lo both continuations apply, and their exponentials cancel:
            # every crown's whole chord lies above z
            below_every_chord = a_val[0] + b_val[0] + s_b[0] * (1.0 - below_d)
            for k in range(z.shape[1]):
                zk = z[r, k]
                if zk < a_lo:
                    depth[r, k] += weight * below_every_chord
                    continue
                # A_j at t = z/b_j; below the grid A(t) = A(lo) + S_b(lo)(1 − e^{−κu(b·lo − z)})
                p = zk * inv_b - start
                if zk < b_lo:
                    total = a_val[0] - s_b[0] * np.expm1(-ku[r, j] * (b_lo - zk))
                elif p < last:  # zero from the top of the grid up
                    total = hermite_at(a_val, a_slope, p)
                else:
                    continue  # z/a_j ≥ z/b_j is beyond the grid too
                # B_j at t = z/a_j; below the grid B(t) = B(lo) + S_b(lo)(e^{−κu(b·lo − z)}
                # − e^{−r_d·lo})
                p = zk * inv_a - start
                if zk < a_lo:
                    total += b_val[0] + s_b[0] * (np.exp(-ku[r, j] * (b_lo - zk)) - below_d)
                elif p < last:
                    total += hermite_at(b_val, b_slope, p)
                depth[r, k] += weight * total


@jit
def cohort_depth_kernel(
    pdf, lo, step, stems, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z, depth
):
    """Add one cohort's tree optical depth at heights z (n, e) to ``depth``.

    From the cohort's height density ``pdf`` (n, nodes) on each row's grid lo + step·i:
    the density scaled to stems per m² times π R(h)² (R = r0 + r1·h), the crown chord
    ends a_j, b_j (crown length ratio ``ratio``) and κu_j = ``extinction``·``node_favd``_j,
    then :func:`_add_tree_depth`: the kernel of :func:`add_cohort_depth`.
    """
    n, nodes = pdf.shape
    n_nodes = s_lo.size
    g = np.empty((n, nodes))
    a = np.empty((n, n_nodes))
    b = np.empty((n, n_nodes))
    ku = np.empty((n, n_nodes))
    mass = np.empty(nodes)
    for r in range(n):
        # mass[0]: the density's integral on the grid
        discounted_tail_row(pdf[r], 0.0, step[r], mass)
        scale = np.pi / 1e4 * stems[r] / (mass[0] if mass[0] > 0.0 else 1.0)
        for i in range(nodes):
            radius = _crown_radius(lo[r] + step[r] * i, r0[r], r1[r])
            g[r, i] = scale * radius * radius * pdf[r, i]
        c = ratio[r]
        for j in range(n_nodes):
            a[r, j] = max(1.0 - c + c * s_lo[j], 1e-12)
            b[r, j] = 1.0 - c + c * s_hi[j]
            ku[r, j] = extinction[r] * node_favd[j]
    _add_tree_depth(g, lo, step, a, b, ku, w, z, depth)


@jit
def point_depth_kernel(
    stems, height, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z, depth
):  # fmt: skip
    """Add the depth of ``stems`` (stems/ha, (n,)) all of height ``height`` (n,) at
    heights z (n, e) to ``depth``: per node j, g·w_j·(1 − e^{−κu_j·max(0, b_j H −
    max(z, a_j H))}) with g = λ·π·Rc(H)²: the kernel of :func:`add_point_depth`."""
    e = z.shape[1]
    for r in range(stems.size):  # no rows at all where the model has no such stems
        if stems[r] <= 0.0:
            continue
        radius = _crown_radius(height[r], r0[r], r1[r])
        g = np.pi / 1e4 * stems[r] * radius * radius
        c = ratio[r]
        for j in range(s_lo.size):
            gw = g * w[r, j]
            if gw == 0.0:
                continue
            bottom = max(1.0 - c + c * s_lo[j], 1e-12) * height[r]
            top = (1.0 - c + c * s_hi[j]) * height[r]
            ku = extinction[r] * node_favd[j]
            whole = -gw * np.expm1(-ku * (top - bottom))  # z below the crown: the whole chord
            for k in range(e):
                if z[r, k] <= bottom:
                    depth[r, k] += whole
                elif z[r, k] < top:
                    depth[r, k] -= gw * np.expm1(-ku * (top - z[r, k]))
