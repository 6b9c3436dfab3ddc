"""Compiled kernels of :mod:`forward.expected` (optional, needs numba).

The tree optical depth, the same quantity as the numpy path of
:meth:`forward.expected.ExpectedWaveformModel._tree_depth`, computed row by row: each
cohort's height density scaled to crown area, the discounted tails S(h_i; r) by their
backward recurrence S_i = e^{−rδ}·S_{i+1} + C_i (C_i the fourth-order cell rule of
:func:`forward.expected_tables.tail_matrix` applied to g(h)·e^{−r(h − h_i)}), the tables
A_j, B_j with their exact slopes, and cubic Hermite reads at z/b_j and z/a_j, with the
exact continuation below the grid (below every chord, z < a_j·lo, the two continuations
sum to a constant: no exponential per height). Then the grid path's assembly of the
samples (:meth:`~forward.expected.ExpectedWaveformModel._canopy_grid`): grid operator,
uniform understory, whole-bin shift; :func:`grid_canopy` runs the depth grid, the depth
and the assembly in one call. All agree with the numpy path to rounding; with a few rows
per call, as a sampler makes them, they save the numpy path's per-call overhead, which
exceeds its arithmetic. :data:`AVAILABLE` is False when numba cannot be imported.
"""

import importlib.util

import numpy as np

from . import expected_ground
from .expected_ground import ground_bins
from .expected_tables import LAGRANGE_CUBIC, MAX_EXPONENT, WEIGHT_SERIES

#: Whether numba is installed (it is imported, and the kernel compiled, on first use).
AVAILABLE = importlib.util.find_spec("numba") is not None

__all__ = [
    "AVAILABLE",
    "add_cohort_depth",
    "assemble_grid",
    "gaussian_ground_return",
    "grid_canopy",
]


def _series(m, x):
    """Row ``m`` of the cell weights' Taylor series at x (Horner's rule)."""
    acc = WEIGHT_SERIES[m, -1]
    for k in range(WEIGHT_SERIES.shape[1] - 2, -1, -1):
        acc = acc * x + WEIGHT_SERIES[m, k]
    return acc


def _cell_weights(x):
    """The four weights of the exponentially fitted cell rule of
    :func:`forward.expected_tables.cell_weights` at x = rate·step, as scalars: Taylor
    series below x = 0.5, moments by recurrence above."""
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


def _discounted(g, rate, step, out):
    """Discounted tails of samples ``g`` (nodes ≥ 4) at ``rate`` (1/m) into ``out``: cells
    by :func:`_cell_weights`, then the backward recurrence."""
    nodes = g.size
    x = rate * step
    w0, w1, w2, w3 = _cell_weights(x)
    rho = np.exp(-x)
    out[nodes - 1] = 0.0
    for i in range(nodes - 2, -1, -1):
        before = g[i - 1] if i > 0 else 3.0 * g[0] - 3.0 * g[1] + g[2]
        after = g[i + 2] if i < nodes - 2 else 3.0 * g[i + 1] - 3.0 * g[i] + g[i - 1]
        cell = w0 * before + w1 * g[i] + w2 * g[i + 1] + w3 * after
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


def _cohort_depth(
    pdf, lo, step, stems, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z, depth
):
    """Add one cohort's tree optical depth at heights z (n, e) to ``depth``.

    From the cohort's height density ``pdf`` (n, nodes) on each row's grid lo + step·i:
    the density scaled to stems per m² times π R(h)² (R = r0 + r1·h), the crown chord
    ends a_j, b_j (crown length ratio ``ratio``) and κu_j = ``extinction``·``node_favd``_j,
    then :func:`_add_tree_depth`; the preparation numpy does in
    :meth:`forward.expected.ExpectedWaveformModel._tree_depth`.
    """
    n, nodes = pdf.shape
    n_nodes = s_lo.size
    g = np.empty((n, nodes))
    a = np.empty((n, n_nodes))
    b = np.empty((n, n_nodes))
    ku = np.empty((n, n_nodes))
    mass = np.empty(nodes)
    for r in range(n):
        _discounted(pdf[r], 0.0, step[r], mass)  # mass[0]: the density's integral on the grid
        scale = np.pi / 1e4 * stems[r] / (mass[0] if mass[0] > 0.0 else 1.0)
        for i in range(nodes):
            radius = r0[r] + r1[r] * (lo[r] + step[r] * i)
            g[r, i] = scale * radius * radius * pdf[r, i]
        c = ratio[r]
        for j in range(n_nodes):
            a[r, j] = max(1.0 - c + c * s_lo[j], 1e-12)
            b[r, j] = 1.0 - c + c * s_hi[j]
            ku[r, j] = extinction[r] * node_favd[j]
    _add_tree_depth(g, lo, step, a, b, ku, w, z, depth)


def _assemble_grid(
    depth,
    matrix,
    first,
    shift,
    interp,
    layers_to_samples,
    under_scale,
    under_top,
    z0,
    layer,
    bins,
    undershoot,
):
    """Canopy samples (n, bins), E[P(0)] (n,) and rows to redo (n,) of the grid path from
    the tree optical depth on each row's grid: E[P] − 1 through the grid operator, the
    uniform understory's Δ(P_trees·P_u) on the layers below its top (``under_scale`` =
    κ·LAI_u/h_u, 0 for none; ``under_top`` = h_u), each row shifted by ``shift`` whole bins
    (what falls outside the window is dropped), and samples below zero clipped keeping the
    row's energy unless they undershoot by more than ``undershoot`` of it (those rows are
    flagged); the assembly numpy does in
    :meth:`forward.expected.ExpectedWaveformModel._canopy_grid`."""
    n, nodes = depth.shape
    width, edges = matrix.shape[1], interp.shape[1]
    lost = np.empty((n, nodes))
    for r in range(n):
        for i in range(nodes):
            lost[r, i] = np.expm1(-depth[r, i])
    local = lost @ matrix
    out = np.zeros((n, bins))
    gap0 = np.empty(n)
    redo = np.zeros(n, np.bool_)
    for r in range(n):
        gap0[r] = 1.0 + lost[r, 0]
        if under_scale[r] > 0.0:
            count = min(int(np.ceil((under_top[r] - z0[r]) / layer)) + 2, edges)
            previous = 0.0
            for e in range(count):
                trees = 1.0
                for i in range(nodes):
                    trees += lost[r, i] * interp[i, e]
                height = max(z0[r] + layer * e, 0.0)
                intercepted = -np.expm1(-under_scale[r] * max(under_top[r] - height, 0.0))
                product = trees * intercepted  # P_trees·(1 − P_u) at the edge
                if e == 0:
                    gap0[r] *= 1.0 - intercepted
                else:  # layer e − 1 gains −Δ(P_trees·(1 − P_u))
                    change = previous - product
                    for k in range(width):
                        local[r, k] += change * layers_to_samples[e - 1, k]
                previous = product
        start = shift[r] + first
        lowest, total, positive = 0.0, 0.0, 0.0
        for k in range(max(0, -start), min(width, bins - start)):
            value = local[r, k]
            out[r, start + k] = value
            lowest = min(lowest, value)
            total += value
            positive += max(value, 0.0)
        if lowest < 0.0:
            redo[r] = lowest < -undershoot * max(1.0 - gap0[r], 2.2250738585072014e-308)
            if not redo[r]:  # clip at zero, keeping the row's energy
                scale = max(total / positive, 0.0) if positive > 0.0 else 0.0
                for j in range(bins):
                    out[r, j] = max(out[r, j], 0.0) * scale
    return out, gap0, redo


def _point_depth(
    stems, height, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z, depth
):  # fmt: skip
    """Add the depth of ``stems`` (stems/ha, (n,)) all of height ``height`` (n,) at
    heights z (n, e) to ``depth``: per node j, g·w_j·(1 − e^{−κu_j·max(0, b_j H −
    max(z, a_j H))}) with g = λ·π·Rc(H)², as
    :func:`forward.expected_depth.add_point_depth` computes it."""
    e = z.shape[1]
    for r in range(stems.size):  # no rows at all where the model has no such stems
        if stems[r] <= 0.0:
            continue
        radius = r0[r] + r1[r] * height[r]
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


def _grid_canopy(
    pdf, lo, step, stems, w, point_stems, point_height, point_w, r0, r1, ratio, s_lo, s_hi,
    extinction, node_favd, z0, grid_step, nodes, matrix, first, shift, interp,
    layers_to_samples, under_scale, under_top, layer, bins, undershoot,
):  # fmt: skip
    """The grid path in one call: each row's depth grid z0 + k·``grid_step`` (clipped at the
    ground), the optical depth of every cohort (``pdf``, ``lo``, ``step``, ``stems`` and
    ``w`` stacked by cohort) as :func:`_cohort_depth` adds it and of the stems of one
    height per row (``point_stems``, ``point_height``, ``point_w``; empty for none)
    as :func:`_point_depth` adds it, then :func:`_assemble_grid`."""
    n = z0.size
    z = np.empty((n, nodes))
    for r in range(n):
        for k in range(nodes):
            z[r, k] = max(z0[r] + grid_step * k, 0.0)
    depth = np.zeros((n, nodes))
    for c in range(pdf.shape[0]):
        _cohort_depth(
            pdf[c], lo[c], step[c], stems[c], r0, r1, ratio, s_lo, s_hi, extinction,
            node_favd, w[c], z, depth,
        )  # fmt: skip
    _point_depth(
        point_stems, point_height, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, point_w,
        z, depth,
    )  # fmt: skip
    return _assemble_grid(
        depth, matrix, first, shift, interp, layers_to_samples, under_scale, under_top, z0,
        layer, bins, undershoot,
    )  # fmt: skip


def _gaussian_ground(
    canopy, gap0, zg, rho_v, rho_g, valid, h_first, scale, sigma, step, first, last
):
    n, bins = canopy.shape
    ground = np.zeros((n, bins))
    total = np.empty((n, bins))
    factor = np.exp(-step * step)
    for r in range(n):
        if not valid[r]:
            canopy[r] = 0.0
            total[r] = 0.0
            continue
        # e^{−d²/2} at d_j = d_k + (j − k)δ from the bin k nearest the ground, by its exact
        # ratios e^{±d_jδ − δ²/2} (each the previous times e^{−δ²}): three exps a row
        offset = (zg[r] - h_first) / (sigma * step)
        k = min(max(first + int(np.floor(offset + 0.5)), first), last - 1)
        d = (k - first - offset) * step
        peak = rho_g[r] * gap0[r] * scale * np.exp(-0.5 * d * d)
        value, ratio = peak, np.exp(-d * step - 0.5 * step * step)
        for j in range(k, last):
            ground[r, j] = value
            value *= ratio
            ratio *= factor
        value, ratio = peak, np.exp(d * step - 0.5 * step * step)
        for j in range(k - 1, first - 1, -1):
            value *= ratio
            ratio *= factor
            ground[r, j] = value
        for j in range(bins):
            canopy[r, j] *= rho_v[r]
            total[r, j] = canopy[r, j] + ground[r, j]
    return total, canopy, ground


_COMPILED = {}

#: The point-mass arrays of a model without such stems: no rows, so nothing is added.
_NO_POINTS = (np.zeros(0), np.zeros(0), np.zeros((0, 0)))


def _kernels():
    """The compiled kernels: helpers are compiled first, so that the kernels call them."""
    if not _COMPILED:
        from numba import njit

        global _series, _cell_weights, _discounted, _hermite, _add_tree_depth
        global _cohort_depth, _assemble_grid, _point_depth
        _series = njit(cache=True)(_series)
        _cell_weights = njit(cache=True)(_cell_weights)
        _discounted = njit(cache=True)(_discounted)
        _hermite = njit(cache=True)(_hermite)
        _add_tree_depth = njit(cache=True)(_add_tree_depth)
        _cohort_depth = njit(cache=True)(_cohort_depth)
        _point_depth = njit(cache=True)(_point_depth)
        _assemble_grid = njit(cache=True)(_assemble_grid)
        _COMPILED["cohort_depth"] = _cohort_depth
        _COMPILED["assemble_grid"] = _assemble_grid
        _COMPILED["point_depth"] = _point_depth
        _COMPILED["grid_canopy"] = njit(cache=True)(_grid_canopy)
        _COMPILED["gaussian_ground"] = njit(cache=True)(_gaussian_ground)
    return _COMPILED


def _f64(x):
    """``x`` as a C-contiguous float64 array (no copy if it already is one)."""
    return np.ascontiguousarray(x, dtype=np.float64)


def add_cohort_depth(
    pdf, lo, step, stems, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z, depth
):
    """Compiled: add one cohort's tree optical depth at heights ``z`` (n, e) to ``depth``
    (updated in place), from its height density on each row's grid (see
    :func:`_cohort_depth`); the same numbers as the numpy path to rounding. Row arrays are
    (n,), node arrays (J,), ``w`` (n, J)."""
    arrays = (pdf, lo, step, stems, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z)
    _kernels()["cohort_depth"](*(_f64(x) for x in arrays), depth)


def add_point_depth(
    stems, height, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z, depth
):  # fmt: skip
    """Compiled: add the depth of stems of one height per row (see :func:`_point_depth`)
    at heights ``z`` (n, e) to ``depth`` (updated in place)."""
    arrays = (stems, height, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, w, z)
    _kernels()["point_depth"](*(_f64(x) for x in arrays), depth)


def assemble_grid(depth, operator, shift, under_scale, under_top, z0, layer, bins, undershoot):
    """Compiled: canopy samples (n, ``bins``), E[P(0)] (n,) and the rows to recompute (n,)
    of the grid path from the tree optical depth on the grid (see :func:`_assemble_grid`).
    ``operator`` is the :func:`forward.expected_tables.grid_operator` tuple of the grid."""
    matrix, first, interp, layers_to_samples = operator
    return _kernels()["assemble_grid"](
        _f64(depth),
        _f64(matrix),
        int(first),
        np.ascontiguousarray(shift, dtype=np.int64),
        _f64(interp),
        _f64(layers_to_samples),
        _f64(under_scale),
        _f64(under_top),
        _f64(z0),
        float(layer),
        int(bins),
        float(undershoot),
    )


def grid_canopy(
    cohorts, points, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, z0, grid_step, nodes,
    operator, shift, under_scale, under_top, layer, bins, undershoot,
):  # fmt: skip
    """Compiled: the grid path's canopy samples (n, ``bins``), E[P(0)] (n,) and rows to
    recompute (n,) in one call, from the cohorts' height densities: ``cohorts`` is a list
    of (pdf (n, nodes), lo (n,), step (n,), stems (n,), w (n, J)), one per cohort with
    trees; ``points`` the (stems (n,), height (n,), w (n, J)) of stems of one height per
    row, or None; the depth grid starts at ``z0`` (n,) and has ``nodes`` points
    ``grid_step`` apart. The same numbers as :func:`add_cohort_depth` and
    :func:`add_point_depth` then :func:`assemble_grid`."""
    matrix, first, interp, layers_to_samples = operator
    if len(cohorts) == 1:  # a view with a leading axis, not a copy
        stacked = [_f64(part)[None] for part in cohorts[0]]
    else:
        stacked = [np.stack([_f64(c[i]) for c in cohorts]) for i in range(5)]
    if points is None:
        points = _NO_POINTS
    return _kernels()["grid_canopy"](
        *stacked, *(_f64(x) for x in points), _f64(r0), _f64(r1), _f64(ratio), _f64(s_lo),
        _f64(s_hi), _f64(extinction), _f64(node_favd), _f64(z0), float(grid_step), int(nodes),
        _f64(matrix), int(first),
        np.ascontiguousarray(shift, dtype=np.int64), _f64(interp), _f64(layers_to_samples),
        _f64(under_scale), _f64(under_top), float(layer), int(bins), float(undershoot),
    )  # fmt: skip


def gaussian_ground_return(
    canopy, gap0, ground_elevation, rho_v, rho_g, valid, heights, dz, pulse, support
):
    """Compiled :func:`forward.expected_ground.ground_return` for a Gaussian pulse, with
    ``heights`` evenly spaced by ``dz``: the same arguments and numbers, to rounding."""
    first, last = ground_bins(heights, ground_elevation, support)
    if last <= first:
        return expected_ground.ground_return(
            canopy, gap0, ground_elevation, rho_v, rho_g, valid, heights, dz, pulse, support
        )
    sigma = pulse.sigma_m
    return _kernels()["gaussian_ground"](
        canopy, _f64(gap0), _f64(ground_elevation), _f64(rho_v), _f64(rho_g),
        np.ascontiguousarray(valid, dtype=np.bool_), float(heights[first]),
        float(dz / (sigma * np.sqrt(2.0 * np.pi))), float(sigma), float(dz / sigma), first, last,
    )  # fmt: skip
