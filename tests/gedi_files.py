"""Small GEDI-L1B-layout files written by the tests, and shots to fill them."""

import h5py
import numpy as np


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
