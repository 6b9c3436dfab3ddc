"""Work follows the scene: behaviour behind ``studies/scaling.py`` (no timings here)."""

import numpy as np

import forward as fw
import forward.explicit.gap as gap_module
from forward.explicit.render import ground_samples


def ring_stand(rng, n, inner, outer):
    r = rng.uniform(inner, outer, n)
    angle = rng.uniform(0.0, 2.0 * np.pi, n)
    return fw.Stand.from_arrays(
        x=r * np.cos(angle),
        y=r * np.sin(angle),
        height=np.full(n, 20.0),
        crown_length=np.full(n, 8.0),
        crown_radius=np.full(n, 1.5),
        favd=0.8,
        shape="cone",
    )


def test_trees_beyond_the_footprint_reach_no_crossing(gedi, rng):
    sim = fw.WaveformSimulator(gedi)
    far = ring_stand(rng, 500, sim.footprint_radius + 2.0, sim.footprint_radius + 80.0)
    assert sim.prepare(far).crowns_near(0.0, 0.0, sim.footprint_radius, fw.Ground()).size == 0
    wf = sim.simulate(far)
    assert wf.canopy_energy == 0.0 and np.all(wf.canopy == 0.0)


def test_empty_scene_is_the_ground_return_alone(gedi):
    sim = fw.WaveformSimulator(gedi)
    wf = sim.simulate(fw.Stand.empty())
    alone = 0.3 * ground_samples(sim, np.zeros(1), np.ones(1), wf.heights)
    np.testing.assert_array_equal(wf.samples, alone)


def test_column_blocks_span_only_their_own_crowns(monkeypatch, gedi, rng):
    """Each block of crowned columns is processed over its own crowns' layer span (the
    numpy kernel's blocks; the compiled kernel walks each column over its own crowns)."""
    spans = []
    original = gap_module._block_losses

    def recording(row, z_low, z_high, extinction, grid, n_rows):
        spans.append((grid.n_layers, n_rows, float(z_low.min()), float(z_high.max()), grid))
        return original(row, z_low, z_high, extinction, grid, n_rows)

    monkeypatch.setattr(gap_module, "_block_losses", recording)
    monkeypatch.setattr(gap_module, "BLOCK_ELEMENTS", 2000)
    low = ring_stand(rng, 20, 0.0, 6.0)
    high = fw.Stand.from_arrays(
        x=[0.0], y=[0.0], height=[60.0], crown_length=[5.0], crown_radius=[1.0], favd=0.8
    )
    stand = fw.Stand(
        *(np.concatenate([getattr(low, c), getattr(high, c)]) for c in
          ("x", "y", "height", "crown_length", "crown_radius")),
        shape=np.concatenate([low.shape, high.shape]),
        favd=np.concatenate([low.favd, high.favd]),
    )  # fmt: skip
    sim = fw.WaveformSimulator(gedi, fw.AccuracySettings(backend="numpy"))
    sim.simulate(stand)
    h = sim.layer_height
    assert len(spans) > 1
    for n_layers, _, z_low, z_high, grid in spans:
        assert grid.bottom <= z_low + 1e-9 and grid.bottom + n_layers * h >= z_high - 1e-9
    # blocks sorted by crown top: far less work than every column over the 12–60 m canopy
    work = sum(n_layers * n_rows for n_layers, n_rows, *_ in spans)
    columns = sum(n_rows for _, n_rows, *_ in spans)
    assert work < 0.4 * columns * (60.0 - 12.0) / h
