"""LVIS L1B reader, tested on small files written here in the mission layout."""

import h5py
import numpy as np
import pytest

from lidarinv.io import iter_observations
from lidarinv.observe import Observation, analyse


def write_lvis(path, n_shots=4, n_bins=1024, ground=(50.0, 51.0, 52.5, 49.2), z_name=None):
    """An LVIS-L1B-layout file with Gaussian ground returns at the given elevations."""
    rng = np.random.default_rng(n_bins)
    dz = 0.15
    ground_bin = n_bins - 200.4
    bins = np.arange(n_bins)
    rx = (
        400.0
        + 300.0 * np.exp(-0.5 * ((bins - ground_bin) / 4.0) ** 2)
        + rng.standard_normal((n_shots, n_bins))
    )
    z0 = np.asarray(ground[:n_shots]) + ground_bin * dz
    with h5py.File(path, "w") as f:
        f["RXWAVE"] = rx.astype(np.uint16)
        f["TXWAVE"] = np.tile(
            np.exp(-0.5 * ((np.arange(128) - 40) / 3.0) ** 2) * 500, (n_shots, 1)
        ).astype(np.uint16)
        f["Z0"] = z0
        f[z_name or f"Z{n_bins - 1}"] = z0 - (n_bins - 1) * dz
        f["LFID"] = np.full(n_shots, 1234567, np.int64)
        f["SHOTNUMBER"] = np.arange(n_shots, dtype=np.int64) + 900
        f["LON0"] = np.linspace(280.0, 280.01, n_shots)
        f["LAT0"] = np.linspace(40.0, 40.01, n_shots)
        f["ZG"] = np.asarray(ground[:n_shots])  # the product's own ground, ignored


@pytest.mark.parametrize("n_bins", [1024, 528, 1216])
def test_read_lvis_release_variants(tmp_path, n_bins):
    path = tmp_path / f"LVIS1B_{n_bins}.h5"
    write_lvis(path, n_bins=n_bins)
    shots = list(iter_observations(path))
    assert [o.shot_id for o in shots] == [900, 901, 902, 903]
    first = shots[0]
    assert isinstance(first, Observation) and first.n_bins == n_bins
    assert first.bin_size == pytest.approx(0.15)
    assert first.metadata["lfid"] == 1234567 and first.metadata["latitude"] == pytest.approx(40.0)
    assert first.pulse.size == 128 and first.pulse_ns == pytest.approx(1.0, rel=1e-3)
    for obs, truth in zip(shots, (50.0, 51.0, 52.5, 49.2)):
        result = analyse(obs)
        assert result.ok and result.ground == pytest.approx(truth, abs=0.02)
        assert np.isnan(obs.noise_mean)  # LVIS gives no noise: it is estimated


def test_lvis_last_bin_mismatch_and_beams(tmp_path):
    path = tmp_path / "bad.h5"
    write_lvis(path, n_bins=528, z_name="Z1023")
    with pytest.raises(ValueError, match="Z1023 but RXWAVE has 528 bins"):
        list(iter_observations(path))
    good = tmp_path / "good.h5"
    write_lvis(good, n_bins=528)
    with pytest.raises(ValueError, match="no beams"):
        list(iter_observations(good, beams=["BEAM0000"]))
    assert [o.shot_id for o in iter_observations(good, shots=slice(1, 3))] == [901, 902]
