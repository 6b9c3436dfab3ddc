"""GEDI L1B reader, tested on small files written here in the mission layout."""

import h5py
import numpy as np
import pytest
from gedi_files import gedi_shot, write_gedi

from lidarinv.io import detect_format, iter_observations
from lidarinv.observe import Observation, ShotError


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
