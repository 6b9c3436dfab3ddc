"""HDF5 output of ``lidarinv simulate``.

Layout (one group per footprint, ``footprint_000``, ``footprint_001``, …; the root holds
the instrument and scene settings as attributes and the stand under ``stand/``):

==================  ===========  ==========================================================
dataset             units        meaning
==================  ===========  ==========================================================
``height``          m            bin-centre height above the ground at the beam centre
``samples``         —            waveform (apparent reflectance per bin)
``canopy``          —            canopy part of ``samples``
``ground``          —            ground part of ``samples``
``gap``             —            footprint-mean gap probability P̄ at the bin centres
``crown_volume``    m³ m⁻²       footprint-weighted crown volume per bin per ground area
``foliage_area``    m² m⁻²       footprint-weighted foliage area per bin per ground area
==================  ===========  ==========================================================

Each footprint group carries ``center_x``, ``center_y`` (m), ``canopy_energy``,
``ground_energy`` and ``ground_gap`` as attributes.
"""

import h5py
import numpy as np

from forward.stand_io import write_stand

_DATASETS = {
    "height": ("heights", "m"),
    "samples": ("samples", "1"),
    "canopy": ("canopy", "1"),
    "ground": ("ground", "1"),
    "gap": ("gap", "1"),
    "crown_volume": ("crown_volume", "m3 m-2"),
    "foliage_area": ("foliage_area", "m2 m-2"),
}


def write_simulation(path, waveforms, stand=None, attributes=None) -> None:
    """Write simulated waveforms (and optionally their stand) to a new HDF5 file."""
    if not waveforms:
        raise ValueError("no waveforms to write")
    from lidarinv import __version__

    with h5py.File(path, "w") as handle:
        handle.attrs["lidarinv_version"] = __version__
        handle.attrs["content"] = "lidarinv simulated waveforms"
        for key, value in {**waveforms[0].settings, **(attributes or {})}.items():
            handle.attrs[key] = value
        for index, wf in enumerate(waveforms):
            group = handle.create_group(f"footprint_{index:03d}")
            for name, (field, unit) in _DATASETS.items():
                group.create_dataset(name, data=getattr(wf, field)).attrs["units"] = unit
            group.attrs["center_x"], group.attrs["center_y"] = wf.center
            group.attrs["canopy_energy"] = wf.canopy_energy
            group.attrs["ground_energy"] = wf.ground_energy
            group.attrs["ground_gap"] = wf.ground_gap
        if stand is not None:
            write_stand(handle.create_group("stand"), stand)


def is_simulation(handle) -> bool:
    """Whether an open HDF5 file holds ``lidarinv simulate`` footprints."""
    return any(name.startswith("footprint_") for name in handle)


def read_simulation(path) -> list[dict]:
    """Read the footprints of a simulation file as dicts of arrays and attributes."""
    with h5py.File(path, "r") as handle:
        names = sorted(k for k in handle if k.startswith("footprint_"))
        if not names:
            raise ValueError(f"{path}: no footprint groups; is this a lidarinv simulation file?")
        out = []
        for name in names:
            group = handle[name]
            record = {key: np.asarray(group[key][()]) for key in _DATASETS}
            record.update({key: group.attrs[key] for key in group.attrs})
            out.append(record)
        return out
