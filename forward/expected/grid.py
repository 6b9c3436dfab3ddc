"""The grid path's assembly of the canopy samples, with numpy and compiled.

The expected model evaluates the trees' optical depth on a grid of whole fine layers
anchored at or below each row's ground on an edge that is both a bin edge and a grid-cell
edge, so that the waveform is continuous in the ground elevation. From there the samples
follow by one constant matrix (:func:`.interpolation.grid_operator`: Catmull–Rom
interpolation to the layer edges, layer energies, pulse), a correction for a uniform
understory below its top, and a shift of each row by whole bins. :func:`assemble_grid` and
:func:`grid_canopy` take ``backend=`` (:mod:`forward.backends`); compiled,
:func:`grid_canopy` runs the depth grid, the depth and the assembly in one call.
"""

import numpy as np

from ..backends import as_float64 as _f64
from ..backends import jit, resolve
from .depth import NO_POINTS, cohort_depth_kernel, point_depth_kernel, tree_depth
from .settings import GRID_BLEND_SD_CELLS


def clip_keeping_energy(canopy, rows):
    """Zero the negative samples of some rows and rescale the rest to keep each row's sum.

    Parameters
    ----------
    canopy : array (n, bins)
        Updated in place.
    rows : array of bool (n,)

    Returns
    -------
    array (n, bins)
        ``canopy``: non-negative samples and exact energy in ``rows`` (a change of the order
        of the undershoot, far below the model error).
    """
    if rows.any():
        part = canopy[rows]
        positive = np.clip(part, 0.0, None)
        total = positive.sum(axis=1)
        scale = np.where(total > 0, part.sum(axis=1) / np.where(total > 0, total, 1.0), 0.0)
        canopy[rows] = positive * np.clip(scale, 0.0, None)[:, None]
    return canopy


def anchor_period(per_cell, oversampling) -> int:
    """Fine layers between the grid path's anchors: the least whole number of both grid
    cells and bins.

    Parameters
    ----------
    per_cell, oversampling : int
        Fine layers per grid cell and per bin.

    Returns
    -------
    int

    Notes
    -----
    As the ground crosses an anchor, the grid's first node moves down by one period; a
    period of whole cells maps the grid's nodes onto themselves, so that the interpolated
    E[P], and the waveform, stay continuous in the ground elevation. Anchored on every bin
    edge (cells five bins thick, say), the nodes moved against the crowns: on a canopy of
    nearly one height the waveform changed by 0.4 % of its peak at a bin edge, a step of
    1.6 in an LVIS shot's log-likelihood on which the MAP search's gradients stalled
    (issue 46).
    """
    return int(np.lcm(per_cell, oversampling))


def grid_weight(narrowest_sd, cell, blend=GRID_BLEND_SD_CELLS):
    """The grid path's share of each row's canopy samples, the per-edge path's the rest.

    Parameters
    ----------
    narrowest_sd : array (n,) (m)
        The smallest height sd of a row's cohorts.
    cell : float (m)
        The depth grid's cell.
    blend : (float, float)
        sd (in cells) below which the grid has no share, and above which it has all.

    Returns
    -------
    array (n,) in [0, 1]
        A smoothstep 3t² − 2t³ in t = (sd/cell − blend[0])/(blend[1] − blend[0]), clipped
        to [0, 1]: continuous with its first derivative, so that the waveform's gradient
        stays continuous in the height sd too.
    """
    low, high = blend
    t = np.clip((np.asarray(narrowest_sd, float) / cell - low) / (high - low), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _add_understory(lost, local, interp, layers_to_samples, under_scale, under_top, z0, layer):
    """Samples (n, width) and E[P(0)] with a uniform understory below its top.

    P = P_trees·P_u differs from P_trees only below the understory top: there the trees'
    E[P] is read at the fine-layer edges from the same grid interpolation, and each
    layer's energy becomes Δ(P_trees·P_u) instead of ΔP_trees. P_u is exact at the edges,
    so its kink at the layer top costs no accuracy.
    """
    top = np.where(under_scale > 0, under_top, 0.0)
    edges = min(int(np.max(np.ceil((top - z0) / layer))) + 2, interp.shape[1])
    z = np.maximum(z0[:, None] + layer * np.arange(edges), 0.0)
    trees = 1.0 + lost @ interp[:, :edges]
    intercepted = -np.expm1(-under_scale[:, None] * np.clip(under_top[:, None] - z, 0.0, None))
    # Δ(P_trees·P_u) − ΔP_trees = −Δ(P_trees·(1 − P_u)); z starts at 0 in every row
    change = -np.diff(trees * intercepted, axis=1)
    local = local + change @ layers_to_samples[: edges - 1]
    return local, (1.0 + lost[:, 0]) * (1.0 - intercepted[:, 0])


def assemble_grid(
    depth, operator, shift, under_scale, under_top, z0, layer, bins, undershoot, *, backend="auto"
):
    """Canopy samples (n, ``bins``), E[P(0)] (n,) and the rows to recompute (n,) from the
    trees' optical depth on each row's grid (n, nodes).

    Parameters
    ----------
    depth : array (n, nodes)
    operator : tuple
        :func:`.interpolation.grid_operator` of the grid.
    shift : array (n,)
        Whole bins from the window's first bin edge to each row's grid.
    under_scale, under_top : arrays (n,)
        κ·LAI_u/h_u (1/m; 0 for rows without an understory) and h_u (m).
    z0 : array (n,) (m)
        Height above the ground of each row's first grid node (≤ 0).
    layer : float (m)
    bins : int
    undershoot : float
        Rows whose samples fall below zero by more than this fraction of their canopy
        energy are flagged; the others are clipped at zero keeping their energy.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"`` (:func:`forward.backends.resolve`).

    Returns
    -------
    canopy : array (n, bins)
        Canopy samples before ρv.
    gap0 : array (n,)
        E[P(0)].
    redo : array of bool (n,)
        Rows whose samples undershoot zero by more than ``undershoot`` of their energy.

    Notes
    -----
    With ΔP = E[P] − 1 on the grid, the samples are ΔP @ M for the grid operator M
    (Catmull–Rom to the layer edges, layer energies P(top) − P(bottom), layer kernel);
    below a uniform understory's top each layer's energy is Δ(P_trees·P_u).
    """
    matrix, first, interp, layers_to_samples = operator
    if resolve(backend) == "numba":
        return _assemble_grid(
            _f64(depth), _f64(matrix), int(first), np.ascontiguousarray(shift, dtype=np.int64),
            _f64(interp), _f64(layers_to_samples), _f64(under_scale), _f64(under_top),
            _f64(z0), float(layer), int(bins), float(undershoot),
        )  # fmt: skip
    n = depth.shape[0]
    lost = np.expm1(-depth)  # E[P] − 1: zero above the trees, so a bare row gives zero
    local = lost @ matrix
    gap0 = 1.0 + lost[:, 0]
    if np.any(under_scale > 0):
        local, gap0 = _add_understory(
            lost, local, interp, layers_to_samples, under_scale, under_top, z0, layer
        )
    # row r's sample k lands in bin shift_r + first + k; bins outside the window go to two
    # spare columns (flat indices: much faster than a 2-D scatter)
    width = bins + 2
    cols = (np.asarray(shift).astype(np.intp) + first)[:, None] + np.arange(matrix.shape[1])
    np.clip(cols, -1, width - 2, out=cols)
    cols += (1 + width * np.arange(n))[:, None]
    out = np.zeros((n, width))
    out.ravel()[cols.ravel()] = local.ravel()
    canopy = out[:, 1:-1]
    lowest = canopy.min(axis=1)
    redo = lowest < -undershoot * np.maximum(1.0 - gap0, np.finfo(float).tiny)
    return clip_keeping_energy(canopy, (lowest < 0) & ~redo), gap0, redo


def grid_canopy(
    cohorts, points, crowns, z0, grid_step, nodes, operator, shift, under_scale, under_top,
    layer, bins, undershoot, *, backend="auto", tables=(None, None, None),
):  # fmt: skip
    """The grid path from the cohorts' height densities to the canopy samples.

    Parameters
    ----------
    cohorts, points, crowns : lists and tuples
        As :func:`.depth.tree_depth` takes them.
    z0 : array (n,) (m)
        Height above the ground of each row's first grid node (≤ 0).
    grid_step : float (m)
        Spacing of the depth grid (whole fine layers).
    nodes : int
        Nodes of the depth grid.
    operator, shift, under_scale, under_top, layer, bins, undershoot
        As :func:`assemble_grid` takes them.
    backend : str
        ``"auto"``, ``"numba"`` or ``"numpy"``: compiled, the depth and the assembly run
        in one call.
    tables : tuple
        numpy only: (tails, a_groups, b_groups) of :func:`.depth.add_cohort_depth`.

    Returns
    -------
    canopy, gap0, redo
        As :func:`assemble_grid`, of the depth :func:`.depth.tree_depth` at the grid
        heights max(z0 + k·``grid_step``, 0).
    """
    if resolve(backend) == "numba" and cohorts:
        matrix, first, interp, layers_to_samples = operator
        if len(cohorts) == 1:  # a view with a leading axis, not a copy
            stacked = [_f64(part)[None] for part in cohorts[0]]
        else:
            stacked = [np.stack([_f64(c[i]) for c in cohorts]) for i in range(5)]
        return _grid_canopy(
            *stacked, *map(_f64, NO_POINTS if points is None else points),
            *map(_f64, crowns), _f64(z0), float(grid_step), int(nodes),
            _f64(matrix), int(first), np.ascontiguousarray(shift, dtype=np.int64),
            _f64(interp), _f64(layers_to_samples), _f64(under_scale), _f64(under_top),
            float(layer), int(bins), float(undershoot),
        )  # fmt: skip
    z = z0[:, None] + grid_step * np.arange(nodes)
    np.maximum(z, 0.0, out=z)
    depth = tree_depth(cohorts, points, crowns, z, backend=backend, tables=tables)
    return assemble_grid(
        depth, operator, shift, under_scale, under_top, z0, layer, bins, undershoot,
        backend=backend,
    )  # fmt: skip


@jit
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
    flagged): the kernel of :func:`assemble_grid`."""
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


@jit
def _grid_canopy(
    pdf, lo, step, stems, w, point_stems, point_height, point_w, r0, r1, ratio, s_lo, s_hi,
    extinction, node_favd, z0, grid_step, nodes, matrix, first, shift, interp,
    layers_to_samples, under_scale, under_top, layer, bins, undershoot,
):  # fmt: skip
    """The grid path in one call: each row's depth grid z0 + k·``grid_step`` (clipped at the
    ground), the optical depth of every cohort (``pdf``, ``lo``, ``step``, ``stems`` and
    ``w`` stacked by cohort) as :func:`cohort_depth_kernel` adds it and of the stems of one
    height per row (``point_stems``, ``point_height``, ``point_w``; empty for none)
    as :func:`point_depth_kernel` adds it, then :func:`_assemble_grid`: the kernel of
    :func:`grid_canopy`."""
    n = z0.size
    z = np.empty((n, nodes))
    for r in range(n):
        for k in range(nodes):
            z[r, k] = max(z0[r] + grid_step * k, 0.0)
    depth = np.zeros((n, nodes))
    for c in range(pdf.shape[0]):
        cohort_depth_kernel(
            pdf[c], lo[c], step[c], stems[c], r0, r1, ratio, s_lo, s_hi, extinction,
            node_favd, w[c], z, depth,
        )  # fmt: skip
    point_depth_kernel(
        point_stems, point_height, r0, r1, ratio, s_lo, s_hi, extinction, node_favd, point_w,
        z, depth,
    )  # fmt: skip
    return _assemble_grid(
        depth, matrix, first, shift, interp, layers_to_samples, under_scale, under_top, z0,
        layer, bins, undershoot,
    )  # fmt: skip
