"""GEDI L1B reader, tested on small files written here in the mission layout."""

import h5py
import numpy as np
import pytest

from lidarinv.io import detect_format, iter_observations
from lidarinv.observe import Observation, ShotError


def write_gedi(path, beams, tx_len=64):
    """Write a GEDI-L1B-layout file.

    ``beams`` maps a beam name to a list of shots, each a dict with ``rx`` (samples in
    time order, top first), ``top``/``bottom`` (elevation of bin 0 and the last bin),
    ``shot``, and optionally ``count`` (to write a wrong rx_sample_count).
    """
    with h5py.File(path, "w") as f:
        for name, shots in beams.items():
            g = f.create_group(name)
            counts = np.array([len(s["rx"]) for s in shots], np.uint16)
            starts = np.concatenate([[1], 1 + np.cumsum(counts)[:-1]]).astype(np.uint64)
            g["rxwaveform"] = np.concatenate([s["rx"] for s in shots]).astype(np.float32)
            g["rx_sample_count"] = np.array(
                [s.get("count", c) for s, c in zip(shots, counts)], np.uint16
            )
            g["rx_sample_start_index"] = starts
            n = len(shots)
            tx = np.exp(-0.5 * ((np.arange(tx_len) - 30.0) / 6.4) ** 2) * 200 + 10
            g["txwaveform"] = np.tile(tx, n).astype(np.float32)
            g["tx_sample_count"] = np.full(n, tx_len, np.uint16)
            g["tx_sample_start_index"] = (1 + tx_len * np.arange(n)).astype(np.uint64)
            g["shot_number"] = np.array([s["shot"] for s in shots], np.uint64)
            g["noise_mean_corrected"] = np.array([s.get("noise_mean", 230.0) for s in shots])
            g["noise_stddev_corrected"] = np.array([s.get("noise_sd", 2.5) for s in shots])
            geo = g.create_group("geolocation")
            geo["elevation_bin0"] = np.array([s["top"] for s in shots])
            geo["elevation_lastbin"] = np.array([s["bottom"] for s in shots])
            geo["latitude_bin0"] = np.array([45.0 + 0.001 * i for i in range(n)])
            geo["longitude_bin0"] = np.array([-70.0 - 0.001 * i for i in range(n)])
            g["stale_return_flag"] = np.zeros(n, np.uint8)  # an extra dataset, ignored


def gedi_shot(shot, ground, n_bins=800, ground_bin=600.3, noise=2.5, rng=None, amplitude=150.0):
    """A noisy Gaussian ground return (time order) whose peak lies at elevation ``ground``."""
    rng = rng or np.random.default_rng(shot)
    bins = np.arange(n_bins)
    rx = 230.0 + amplitude * np.exp(-0.5 * ((bins - ground_bin) / 6.4) ** 2)
    rx += 60.0 * np.exp(-0.5 * ((bins - ground_bin + 110) / 15) ** 2)  # a canopy layer above
    rx += noise * rng.standard_normal(n_bins)
    dz = 0.15
    top = ground + ground_bin * dz
    return {"rx": rx, "top": top, "bottom": top - (n_bins - 1) * dz, "shot": shot}


@pytest.fixture
def gedi_file(tmp_path):
    path = tmp_path / "GEDI01_B_test.h5"
    beams = {
        "BEAM0000": [gedi_shot(1000 + i, 300.0 + i) for i in range(3)],
        "BEAM0101": [
            gedi_shot(2000 + i, 500.0 + i, n_bins=600, ground_bin=450.6) for i in range(2)
        ],
    }
    write_gedi(path, beams)
    return path, beams


def test_detect_and_read_every_shot(gedi_file):
    path, beams = gedi_file
    with h5py.File(path) as f:
        assert detect_format(f) == "gedi-l1b"
    shots = list(iter_observations(path))
    assert [o.shot_id for o in shots] == [1000, 1001, 1002, 2000, 2001]
    for obs in shots:
        assert isinstance(obs, Observation) and obs.axis_kind == "elevation"
    first = shots[0]
    raw = beams["BEAM0000"][0]
    # ascending axis: the last time sample comes first
    np.testing.assert_allclose(first.samples, raw["rx"][::-1].astype(np.float32))
    assert first.axis[0] == pytest.approx(raw["bottom"]) and first.axis[-1] == pytest.approx(
        raw["top"]
    )
    assert first.bin_size == pytest.approx(0.15)
    assert first.noise_mean == 230.0 and first.noise_sigma == 2.5
    assert first.pulse.size == 64 and first.pulse_ns == 1.0
    assert first.instrument == "gedi" and isinstance(first.shot_id, int)
    assert first.metadata["beam"] == "BEAM0000"
    assert first.metadata["latitude"] == pytest.approx(45.0)
    assert shots[3].n_bins == 600  # windows differ in length between shots


def test_ground_elevation_from_a_gedi_file(gedi_file):
    from lidarinv.observe import analyse

    path, _ = gedi_file
    for obs in iter_observations(path):
        result = analyse(obs)
        truth = 300.0 + (obs.shot_id - 1000) if obs.shot_id < 2000 else 500.0 + (obs.shot_id - 2000)
        assert result.ok
        assert result.ground == pytest.approx(truth, abs=0.02)


def test_beam_and_shot_selection(gedi_file):
    path, _ = gedi_file
    picked = list(iter_observations(path, beams=["0101"]))
    assert [o.shot_id for o in picked] == [2000, 2001]
    picked = list(iter_observations(path, beams=["BEAM0000"], shots=[2, 0]))
    assert [o.shot_id for o in picked] == [1000, 1002]
    with pytest.raises(ValueError, match="no beam"):
        list(iter_observations(path, beams=["BEAM1011"]))
    with pytest.raises(ValueError, match="shot indices"):
        list(iter_observations(path, beams=["BEAM0000"], shots=[7]))


def test_truncated_and_bad_shots_are_reported_not_raised(tmp_path):
    shots = [gedi_shot(1, 100.0), gedi_shot(2, 100.0), gedi_shot(3, 100.0)]
    shots[1]["rx"][5] = np.nan
    shots[2]["count"] = 5000  # claims more samples than are stored
    path = tmp_path / "bad.h5"
    write_gedi(path, {"BEAM0010": shots})
    out = list(iter_observations(path, format="gedi-l1b"))
    assert isinstance(out[0], Observation)
    assert isinstance(out[1], ShotError) and "NaN" in out[1].reason
    assert isinstance(out[2], ShotError) and "truncated" in out[2].reason


def test_wrong_format_is_a_clear_error(gedi_file, tmp_path):
    path, _ = gedi_file
    with pytest.raises(ValueError, match="lvis-l1b layout"):
        list(iter_observations(path, format="lvis-l1b"))
    with pytest.raises(ValueError, match="unknown format"):
        list(iter_observations(path, format="icesat"))
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["something"] = np.zeros(3)
    with pytest.raises(ValueError, match="not a recognised"):
        list(iter_observations(other))
    simulated = tmp_path / "simulated.h5"  # `lidarinv simulate` output: no noise, no gain
    with h5py.File(simulated, "w") as f:
        f["footprint_000/samples"] = np.zeros(3)
    with pytest.raises(ValueError, match="noise-free waveforms from 'lidarinv simulate'"):
        list(iter_observations(simulated))
