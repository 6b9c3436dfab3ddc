"""The lidarinv HDF5 waveform layout: round trips, stands, streaming and bad input."""

import h5py
import numpy as np
import pytest

import forward as fw
from lidarinv.io import (
    detect_format,
    iter_observations,
    read_observations,
    read_stand_from,
    write_observations,
)
from lidarinv.observe import Observation, observe


@pytest.fixture(scope="module")
def simulated():
    inst = fw.instrument_preset("lvis")
    rng = np.random.default_rng(31)
    stand = fw.Stand.from_arrays(x=rng.uniform(-20, 20, 12), y=rng.uniform(-20, 20, 12),
                                 height=rng.uniform(10, 25, 12), crown_length=np.full(12, 6.0),
                                 crown_radius=np.full(12, 3.0), favd=0.6, shape="cone")  # fmt: skip
    sim = fw.WaveformSimulator(inst)
    obs = []
    for i, centre in enumerate([(0.0, 0.0), (5.0, 5.0), (-5.0, 2.0)]):
        wf = sim.simulate(stand, center=centre)
        obs.append(observe(wf, gain=800.0, baseline=12.0, noise_sigma=0.8, shot_factor=0.1,
                           rng=rng, quantise=True, saturation=400.0, floor_sigmas=2.0 if i == 1 else None,
                           ground_elevation=150.0 + i, shot_id=100 + i,
                           pulse=np.exp(-0.5 * ((np.arange(40) - 20) / 4.0) ** 2),
                           pulse_ns=1.0, metadata={"center_x": centre[0], "site": "plot A"}))  # fmt: skip
    return inst, stand, obs


def test_round_trip_keeps_everything(tmp_path, simulated):
    inst, stand, obs = simulated
    path = tmp_path / "obs.h5"
    write_observations(path, obs, stand=stand, instrument=inst, attrs={"study": "test"})
    with h5py.File(path) as f:
        assert detect_format(f) == "lidarinv"
        assert f["instrument"].attrs["instrument"] == "lvis"
        assert f["waveforms/axis_bin0"].attrs["units"] == "m"
    back = read_observations(path)
    assert len(back) == 3
    for a, b in zip(obs, back):
        np.testing.assert_array_equal(a.samples, b.samples)
        np.testing.assert_allclose(a.axis, b.axis, atol=1e-9)
        assert b.axis_kind == "elevation" and b.shot_id == a.shot_id
        np.testing.assert_array_equal(a.censored_mask, b.censored_mask)
        for name in ("noise_mean", "noise_sigma", "floor", "saturation", "pulse_ns"):
            assert np.isnan(getattr(b, name)) == np.isnan(getattr(a, name))
            if not np.isnan(getattr(a, name)):
                assert getattr(b, name) == getattr(a, name)
        np.testing.assert_allclose(a.pulse, b.pulse)
        assert b.metadata == a.metadata
        assert b.truth["ground"] == a.truth["ground"] and b.truth["gain"] == 800.0
        np.testing.assert_allclose(b.truth["signal"], a.truth["signal"])
    assert back[1].censored is not None and back[1].censored.any()
    stored = read_stand_from(path)
    np.testing.assert_allclose(stored.height, stand.height)
    np.testing.assert_allclose(stored.x, stand.x)


def test_windows_of_different_lengths_and_string_ids(tmp_path):
    rng = np.random.default_rng(0)
    obs = [Observation(rng.normal(size=n), 0.15 * np.arange(n) - 3.0, shot_id=f"s{n}")
           for n in (50, 120, 80)]  # fmt: skip
    path = tmp_path / "ragged.h5"
    write_observations(path, obs)
    back = read_observations(path)
    assert [b.n_bins for b in back] == [50, 120, 80]
    assert [b.shot_id for b in back] == ["s50", "s120", "s80"]
    assert back[0].pulse is None and back[0].censored is None and back[0].axis_kind == "height"
    assert [b.shot_id for b in iter_observations(path, shots=[2])] == ["s80"]


def test_streaming_reads_in_chunks(tmp_path, monkeypatch):
    import lidarinv.io._common as common

    monkeypatch.setattr(common, "CHUNK", 4)
    axis = 0.15 * np.arange(30)
    obs = [
        Observation(np.full(30, float(i)) + np.arange(30) % 3, axis, shot_id=i) for i in range(11)
    ]
    path = tmp_path / "many.h5"
    write_observations(path, obs)
    ids = [o.shot_id for o in iter_observations(path, shots=slice(1, None, 2))]
    assert ids == [1, 3, 5, 7, 9]
    assert [o.samples[0] for o in iter_observations(path)] == [float(i) for i in range(11)]


def test_sparse_selections_never_read_large_blocks():
    from lidarinv.io._common import chunks

    index = np.array([0, 1, 2, 3, 50, 51, 10**6])
    parts = list(chunks(index, 4))
    assert [p.tolist() for p, _, _ in parts] == [[0, 1, 2, 3], [50, 51], [10**6]]
    assert all(hi - lo <= 16 for _, lo, hi in parts)


def test_bad_observations_are_rejected():
    axis = np.arange(10.0)
    with pytest.raises(ValueError, match="NaN"):
        Observation(np.where(axis > 4, np.nan, 1.0), axis)
    with pytest.raises(ValueError, match="empty"):
        Observation(np.array([]), np.array([]))
    with pytest.raises(ValueError, match="ragged"):
        Observation(np.ones(10), np.arange(9.0))
    with pytest.raises(ValueError, match="increasing"):
        Observation(np.ones(10), axis[::-1])
    with pytest.raises(ValueError, match="uniformly"):
        Observation(np.ones(10), axis**2)
    with pytest.raises(ValueError, match="floor"):
        Observation(np.ones(10), axis, censored=axis < 3)


def test_write_rejects_bad_sets(tmp_path):
    with pytest.raises(ValueError, match="no observations"):
        write_observations(tmp_path / "x.h5", [])
    a = Observation(np.ones(5), np.arange(5.0))
    b = Observation(np.ones(5), np.arange(5.0), axis_kind="elevation")
    with pytest.raises(ValueError, match="mix axis kinds"):
        write_observations(tmp_path / "x.h5", [a, b])


def test_64_bit_shot_numbers_survive_the_round_trip(tmp_path):
    from lidarinv.io.waveforms import read_observations, write_observations
    from lidarinv.observe.observation import Observation

    shot = 123456789012345678  # beyond float64's exact integers
    path = tmp_path / "shots.h5"
    write_observations(path, [Observation(np.arange(5.0), np.arange(5.0), shot_id=shot)])
    assert read_observations(path)[0].shot_id == shot
