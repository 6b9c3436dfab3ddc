"""Footprint sums over a grid of columns: the compiled kernel (needs numba).

:func:`footprint_profiles` has the arguments and results of
:func:`forward.explicit.column_kernel.footprint_profiles` and agrees with it to rounding; it works
column by column, so its memory is the crown lists of the bins and a few arrays over the
layers, whatever the number or size of the crowns.

For each bin of columns the crowns whose discs reach it are copied together. For each
column, every crown over it adds its optical-depth ramp, a kink of +k·G·Ω·u where the
column enters the crown and −k·G·Ω·u where it leaves; the kinks are shared linearly by
the two nearest layer edges, so that a running sum of them from the top gives each
layer's optical depth Δτ exactly (:mod:`forward.explicit.gap`). Walking down the column, the gap
P falls by the factor exp(−Δτ) in each layer and the layer returns ω·P·(1 − exp(−Δτ)),
with 1 − exp(−Δτ) taken to full relative precision for thin layers; one exponential is
taken per run of layers at one Δτ, not per layer. :func:`ground_gap` adds each crown's
optical depth to the columns of its disc, row by row (one compiled loop per crown
shape), then sums ω·exp(−τ). The kernels are compiled through :func:`forward.backends.jit`
(on first use, cached on disk); :mod:`forward.explicit.column_kernel` chooses between them
and the numpy reference with ``backend=`` (:func:`forward.backends.resolve`).
"""

import numpy as np

from ..backends import AVAILABLE, jit
from ..crowns import CROWN_SHAPES, SHAPE_NAMES
from .column_grid import ColumnGrid, CrownSet, FootprintSums
from .gap import LayerGrid, layer_integral

__all__ = ["AVAILABLE", "crown_node_ranges", "footprint_profiles", "ground_gap"]

#: Shape codes, in the order of :data:`forward.crowns.SHAPE_NAMES`.
_CONE, _ELLIPSOID, _HEMI_ELLIPSOID, _CYLINDER = (
    SHAPE_NAMES.index(name) for name in ("cone", "ellipsoid", "hemi-ellipsoid", "cylinder")
)

#: The shape registry's extents (:mod:`forward.crowns`), compiled to be inlined.
_cone, _ellipsoid, _hemi_ellipsoid, _cylinder = (
    jit(CROWN_SHAPES[name].extent, inline="always")
    for name in ("cone", "ellipsoid", "hemi-ellipsoid", "cylinder")
)

#: Below this optical depth, 1 − exp(−Δτ) is summed from its series (five terms leave
#: less than Δτ⁵/720 ≤ 2e-18 relative error); above it, 1 − exp(−Δτ) loses at most
#: 1e-13 relative to rounding.
_SERIES_DEPTH = 1e-3


@jit(inline="always")
def _extent(code, rho):
    """Crown interval (s_low, s_high) at normalised radius ``rho``: the shape registry's
    extents (:mod:`forward.crowns`), compiled and chosen by code."""
    if code == _CONE:
        return _cone(rho)
    if code == _ELLIPSOID:
        return _ellipsoid(rho)
    if code == _HEMI_ELLIPSOID:
        return _hemi_ellipsoid(rho)
    return _cylinder(rho)


@jit(inline="always")
def _transmission(depth):
    """exp(−depth) and 1 − exp(−depth), the latter to full relative precision."""
    if depth < _SERIES_DEPTH:
        d = depth
        loss = d * (1.0 - d * (0.5 - d * (1.0 / 6.0 - d * (1.0 / 24.0 - d / 120.0))))
        return 1.0 - loss, loss
    q = np.exp(-depth)
    return q, 1.0 - q


@jit
def _bin_lists(first, last, bin_nodes, n_bins, x, y, radius, code, base, length, ext, favd):
    """Crown records of every bin, stored bin after bin (a CSR layout).

    Returns the bin offsets (n_bins² + 1), the records (x, y, R², 1/R, base, length,
    k·G·Ω·u, u) and the shape codes of the crowns listed in each bin."""
    counts = np.zeros(n_bins * n_bins + 1, np.int64)
    for c in range(x.size):
        for bi in range(first[c, 0] // bin_nodes, last[c, 0] // bin_nodes + 1):
            for bj in range(first[c, 1] // bin_nodes, last[c, 1] // bin_nodes + 1):
                counts[bi * n_bins + bj + 1] += 1
    for k in range(n_bins * n_bins):
        counts[k + 1] += counts[k]
    fill = counts[:-1].copy()
    records = np.empty((counts[-1], 8))
    codes = np.empty(counts[-1], np.int64)
    for c in range(x.size):
        for bi in range(first[c, 0] // bin_nodes, last[c, 0] // bin_nodes + 1):
            for bj in range(first[c, 1] // bin_nodes, last[c, 1] // bin_nodes + 1):
                k = fill[bi * n_bins + bj]
                fill[bi * n_bins + bj] += 1
                records[k, 0], records[k, 1] = x[c], y[c]
                records[k, 2], records[k, 3] = radius[c] * radius[c], 1.0 / radius[c]
                records[k, 4], records[k, 5] = base[c], length[c]
                records[k, 6], records[k, 7] = ext[c], favd[c]
                codes[k] = code[c]
    return counts, records, codes


@jit(inline="always")
def _add_kink(array, position, value):
    """Share ``value`` at fractional edge ``position`` (≥ 0) linearly between its two
    edges; returns the upper one."""
    node = int(position)
    frac = position - node
    array[node] += value * (1.0 - frac)
    array[node + 1] += value * frac
    return node


#: A column with more crown edges than this is walked layer by layer instead of run by
#: run: sorting many edges costs more than the scan.
_MOST_SORTED = 8


@jit(inline="always")
def _sort_marks(values, count):
    """Sort ``values[:count]`` in place by insertion (a few crown edges)."""
    for i in range(1, count):
        value = values[i]
        j = i - 1
        while j >= 0 and values[j] > value:
            values[j + 1] = values[j]
            j -= 1
        values[j + 1] = value


@jit(inline="always")
def _run(returns, first, stop, p, depth_rate, h):
    """Walk layers [first, stop) at a constant optical depth per metre ``depth_rate``:
    each layer returns ω·P·(1 − exp(−Δτ)) and passes ω·P·exp(−Δτ) on. Returns ω·P
    below the last layer."""
    if depth_rate > 0.0 and stop > first:
        q, loss = _transmission(h * depth_rate)
        for t in range(first, stop):
            returns[t] += p * loss
            p *= q
    return p


@jit(inline="always")
def _walk(returns, kinks, marks, count, p, h):
    """Walk one column down through its crowns, from ω·P = ``p`` at its top; returns
    ω·P below its lowest crown.

    ``marks[:count]`` are the upper edges of its kinks (each kink sits on that edge and
    the next); the kinks are consumed (set to zero). Between marked edges the optical
    depth per layer is constant: with few marks they are sorted and each run of layers
    costs one exponential; with many, the column is scanned layer by layer, with one
    exponential per change of depth.
    """
    if count > _MOST_SORTED:
        first, last = marks[0], marks[0]
        for k in range(1, count):
            first, last = min(first, marks[k]), max(last, marks[k])
        rate, q, loss = 0.0, 1.0, 0.0
        for t in range(first, last + 2):
            kink = kinks[t]
            if kink != 0.0:
                kinks[t] = 0.0
                rate += kink
                q, loss = _transmission(h * rate) if rate > 0.0 else (1.0, 0.0)
            returns[t] += p * loss
            p *= q
        return p
    _sort_marks(marks, count)
    rate, i = 0.0, 0
    while i < count:
        t = marks[i]
        while i < count and marks[i] == t:
            i += 1
        rate += kinks[t]
        kinks[t] = 0.0
        p = _run(returns, t, t + 1, p, rate, h)  # the layer below edge t
        rate += kinks[t + 1]
        kinks[t + 1] = 0.0
        p = _run(returns, t + 1, marks[i] if i < count else t + 1, p, rate, h)
    return p


@jit
def _footprint_sums(
    nodes, weights, r2, first, last, bin_nodes,
    x, y, radius, code, base, length, ext, favd,
    top, h, n_layers, gx, gy, sloped, ground_first, n_ground,
):  # fmt: skip
    """Compiled :func:`forward.explicit.column_kernel.footprint_profiles`: the layer returns and
    the kinks of crown volume and foliage (edges counted from ``top``), and the ground
    masses on sloped ground."""
    n = nodes.size
    n_bins = (n + bin_nodes - 1) // bin_nodes
    offsets, rec, codes = _bin_lists(
        first, last, bin_nodes, n_bins, x, y, radius, code, base, length, ext, favd
    )
    n_edges = n_layers + 1
    returns = np.zeros(n_edges + 1)
    kinks = np.zeros(n_edges + 1)
    volume = np.zeros(n_edges + 1)
    foliage = np.zeros(n_edges + 1)
    ground = np.zeros(n_ground + 1)
    most = max(1, np.max(np.diff(offsets)))  # crowns listed in the fullest bin
    marks = np.empty(2 * most, np.int64)
    hits = np.empty(most + 1, np.int64)
    distance2 = np.empty(most + 1)
    inv_h = 1.0 / h
    for bi in range(n_bins):
        for bj in range(n_bins):
            m0, m1 = offsets[bi * n_bins + bj], offsets[bi * n_bins + bj + 1]
            if m1 == m0 and not sloped:
                continue
            for i in range(bi * bin_nodes, min(n, (bi + 1) * bin_nodes)):
                px = nodes[i]
                for j in range(bj * bin_nodes, min(n, (bj + 1) * bin_nodes)):
                    py = nodes[j]
                    if px * px + py * py > r2:
                        continue
                    w = weights[i] * weights[j]
                    z_ground = gx * px + gy * py
                    n_hit = 0  # the bin's crowns over this column, listed without branching
                    for m in range(m0, m1):
                        dx, dy = px - rec[m, 0], py - rec[m, 1]
                        hits[n_hit], distance2[n_hit] = m, dx * dx + dy * dy
                        n_hit += distance2[n_hit] < rec[m, 2]
                    count = 0
                    for k in range(n_hit):
                        m = hits[k]
                        s_low, s_high = _extent(codes[m], np.sqrt(distance2[k]) * rec[m, 3])
                        z_low = rec[m, 4] + s_low * rec[m, 5]
                        z_high = rec[m, 4] + s_high * rec[m, 5]
                        if sloped:  # foliage below the local ground surface does not exist
                            z_low, z_high = max(z_low, z_ground), max(z_high, z_ground)
                        if z_high <= z_low:
                            continue
                        a, wu = rec[m, 6], w * rec[m, 7]
                        # edges counted from the top; clamped against rounding at the ends
                        upper = min(max((top - z_high) * inv_h, 0.0), n_layers)
                        lower = min(max((top - z_low) * inv_h, 0.0), n_layers)
                        marks[count] = _add_kink(kinks, upper, a)
                        marks[count + 1] = _add_kink(kinks, lower, -a)
                        count += 2
                        _add_kink(volume, upper, w)
                        _add_kink(volume, lower, -w)
                        _add_kink(foliage, upper, wu)
                        _add_kink(foliage, lower, -wu)
                    p = _walk(returns, kinks, marks, count, w, h) if count else w
                    if sloped:
                        _add_kink(ground, z_ground * inv_h - ground_first, p)
    return returns[:n_layers], volume, foliage, ground[:n_ground]


#: Ground height (m) that cuts no crown: finite, since the ground pass is compiled with
#: fast math (which assumes no infinities).
_FAR_BELOW = -1e300


@jit(inline="always")
def _chord(nodes, lo, hi, centre, half, start, stop):
    """Range [start, stop) of the nodes among ``nodes[lo:hi]`` (ascending) that lie
    within ``half`` of ``centre``, stepped from the range ``start, stop`` of the row
    before (a crown's chords change little from row to row)."""
    while start > lo and nodes[start - 1] >= centre - half:
        start -= 1
    while start < hi and nodes[start] < centre - half:
        start += 1
    stop = max(stop, start)
    while stop < hi and nodes[stop] <= centre + half:
        stop += 1
    while stop > start and nodes[stop - 1] > centre + half:
        stop -= 1
    return start, stop


@jit(inline="always")
def _crown_depth_row(row, nodes, start, stop, dy0, dx2, inv_r, r2, depth_per_m, extent, z):
    """Add one crown's optical depth to ``row[start:stop]``, columns ``nodes - dy0``
    across from its stem (``dx2`` the squared distance along the other axis); ``z`` =
    (base, length, ground gradient along the row, ground height at node 0 of the row)
    cuts the crown at the local ground (:data:`_FAR_BELOW` on flat ground)."""
    base, length, slope, ground0 = z
    for j in range(start, stop):
        dy = nodes[j] - dy0
        d2 = dx2 + dy * dy
        s_low, s_high = extent(min(np.sqrt(d2) * inv_r, 1.0))
        z_ground = ground0 + slope * nodes[j]  # foliage below the ground does not exist
        path = max(base + s_high * length, z_ground) - max(base + s_low * length, z_ground)
        row[j] += depth_per_m * path * (d2 < r2)


@jit(fastmath=True)
def _ground_gap(
    nodes, weights, r2, first, last, x, y, radius, code, base, length, ext,
    gx, gy, sloped, ground_first, n_ground, inv_h,
):  # fmt: skip
    """Compiled :func:`forward.explicit.column_kernel.ground_gap`: each crown adds its optical
    depth to the columns of its disc, row by row, then Σ ω·exp(−τ) (and the ground
    masses on sloped ground)."""
    n = nodes.size
    depth = np.zeros((n, n))
    for c in range(x.size):
        r_c2, inv_r = radius[c] * radius[c], 1.0 / radius[c]
        start = stop = (first[c, 1] + last[c, 1] + 1) // 2
        for i in range(first[c, 0], last[c, 0] + 1):
            dx2 = (nodes[i] - x[c]) ** 2
            half = np.sqrt(max(r_c2 - dx2, 0.0)) * (1.0 + 1e-9)  # the chord, padded
            start, stop = _chord(nodes, first[c, 1], last[c, 1] + 1, y[c], half, start, stop)
            z = (base[c], length[c], gy, gx * nodes[i] if sloped else _FAR_BELOW)
            row, k, a = depth[i], code[c], ext[c]
            if k == _CONE:  # one loop per shape, so that each compiles to straight code
                _crown_depth_row(row, nodes, start, stop, y[c], dx2, inv_r, r_c2, a, _cone, z)
            elif k == _ELLIPSOID:
                _crown_depth_row(row, nodes, start, stop, y[c], dx2, inv_r, r_c2, a, _ellipsoid, z)
            elif k == _HEMI_ELLIPSOID:
                _crown_depth_row(
                    row, nodes, start, stop, y[c], dx2, inv_r, r_c2, a, _hemi_ellipsoid, z
                )
            else:
                _crown_depth_row(row, nodes, start, stop, y[c], dx2, inv_r, r_c2, a, _cylinder, z)
    total = 0.0
    ground = np.zeros(n_ground + 1)
    start = stop = n // 2
    for i in range(n):
        half = np.sqrt(max(r2 - nodes[i] * nodes[i], 0.0))
        start, stop = _chord(nodes, 0, n, 0.0, half, start, stop)
        row = 0.0
        for j in range(max(start - 1, 0), min(stop + 1, n)):  # the disc's test decides
            if nodes[i] * nodes[i] + nodes[j] * nodes[j] > r2:
                continue
            tau = depth[i, j]
            gap = weights[j] * np.exp(-tau) if tau > 0.0 else weights[j]
            row += gap
            if sloped:
                z_ground = gx * nodes[i] + gy * nodes[j]
                _add_kink(ground, z_ground * inv_h - ground_first, weights[i] * gap)
        total += weights[i] * row
    return total, ground[:n_ground]


#: Most buckets per node of :func:`crown_node_ranges`' lookup table.
_BUCKETS_PER_NODE = 8


def crown_node_ranges(grid: ColumnGrid, crowns: CrownSet):
    """Compiled :func:`forward.explicit.column_grid.crown_node_ranges` (same arguments, same
    results).

    The nodes are few and the crowns of a realised stand many (thousands of small crowns
    in a dense draw): each crown edge is found from a table of the nodes over equal
    buckets of the axis, then stepped to the exact node, in place of a binary search per
    key.
    """
    f64 = np.ascontiguousarray
    return _crown_node_ranges(
        f64(grid.nodes, float), *(f64(a, float) for a in (crowns.x, crowns.y, crowns.radius))
    )


@jit
def _crown_node_ranges(nodes, x, y, radius):
    m = nodes.size
    if m == 0:  # no node: every crown holds none
        return np.zeros((x.size, 2), np.int64), np.full((x.size, 2), -1, np.int64)
    low, span = nodes[0], nodes[m - 1] - nodes[0]
    closest = np.min(np.diff(nodes)) if m > 1 else 0.0
    size = max(1, min(_BUCKETS_PER_NODE * m, int(span / closest) + 1)) if closest > 0 else 1
    width = span / size if span > 0 else 1.0
    below = np.empty(size + 1, np.int64)  # nodes at or below each bucket's lower edge
    j = 0
    for b in range(size + 1):
        while j < m and nodes[j] <= low + b * width:
            j += 1
        below[b] = j
    first = np.empty((x.size, 2), np.int64)
    last = np.empty((x.size, 2), np.int64)
    for i in range(x.size):
        for axis in range(2):
            centre = x[i] if axis == 0 else y[i]
            first[i, axis] = _nodes_up_to(nodes, below, low, width, centre - radius[i], True)
            last[i, axis] = _nodes_up_to(nodes, below, low, width, centre + radius[i], False) - 1
    return first, last


@jit(inline="always")
def _nodes_up_to(nodes, below, low, width, value, inclusive):
    """The number of nodes ≤ ``value`` (``inclusive``) or < it: numpy's searchsorted
    ``side="right"`` or ``"left"``, from the bucket's count stepped to the exact node."""
    m = nodes.size
    b = min(max(int((value - low) / width), 0), below.size - 1) if value > low else 0
    k = max(below[b] - 1, 0)
    while k > 0 and (nodes[k - 1] > value if inclusive else nodes[k - 1] >= value):
        k -= 1
    while k < m and (nodes[k] <= value if inclusive else nodes[k] < value):
        k += 1
    return k


def footprint_profiles(
    grid: ColumnGrid,
    crowns: CrownSet,
    layers: LayerGrid,
    slope=(0.0, 0.0),
    ground_nodes=None,
    bin_nodes=16,
) -> FootprintSums:
    """Compiled :func:`forward.explicit.column_kernel.footprint_profiles` (same arguments, same
    results to rounding)."""
    first, last = crown_node_ranges(grid, crowns)
    top = layers.bottom + layers.n_layers * layers.thickness
    sloped = ground_nodes is not None
    ground_first, n_ground = ground_nodes if sloped else (0, 0)
    f64 = np.ascontiguousarray
    returns, volume, foliage, ground = _footprint_sums(
        f64(grid.nodes, float), f64(grid.weights, float), float(grid.radius) ** 2,
        first, last, int(bin_nodes),
        *(f64(a, float) for a in (crowns.x, crowns.y, crowns.radius)),
        f64(crowns.shape, np.int64),
        *(f64(a, float) for a in (crowns.base, crowns.length, crowns.extinction, crowns.favd)),
        float(top), float(layers.thickness), int(layers.n_layers),
        float(slope[0]), float(slope[1]), sloped, int(ground_first), int(n_ground),
    )  # fmt: skip
    h, n_edges = layers.thickness, layers.n_layers + 1
    volume, foliage = (layer_integral(k[:n_edges, None], h)[::-1, 0] for k in (volume, foliage))
    return FootprintSums(returns[::-1].copy(), volume, foliage, ground if sloped else None)


def ground_gap(grid: ColumnGrid, crowns: CrownSet, slope=(0.0, 0.0), ground_nodes=None, h=1.0):
    """Compiled :func:`forward.explicit.column_kernel.ground_gap` (same arguments, same results to
    rounding)."""
    first, last = crown_node_ranges(grid, crowns)
    sloped = ground_nodes is not None
    ground_first, n_ground = ground_nodes if sloped else (0, 0)
    f64 = np.ascontiguousarray
    gap, ground = _ground_gap(
        f64(grid.nodes, float), f64(grid.weights, float), float(grid.radius) ** 2, first, last,
        *(f64(a, float) for a in (crowns.x, crowns.y, crowns.radius)),
        f64(crowns.shape, np.int64),
        *(f64(a, float) for a in (crowns.base, crowns.length, crowns.extinction)),
        float(slope[0]), float(slope[1]), sloped, int(ground_first), int(n_ground), 1.0 / h,
    )  # fmt: skip
    return float(gap), (ground if sloped else None)
