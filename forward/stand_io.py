"""Stands in HDF5: one group holding the stem-map columns as 1-D datasets."""

import h5py
import numpy as np

from .crowns import SHAPE_NAMES
from .stand import OPTIONAL_COLUMNS, REQUIRED_COLUMNS, Stand

_UNITS = {
    "x": "m",
    "y": "m",
    "height": "m",
    "crown_length": "m",
    "crown_radius": "m",
    "favd": "m2 m-3",
    "dbh": "cm",
}


def write_stand(group: h5py.Group, stand: Stand) -> None:
    """Store a stand in an open HDF5 group.

    Parameters
    ----------
    group : h5py.Group
    stand : Stand

    Notes
    -----
    Layout: float64 datasets ``x, y, height, crown_length, crown_radius, favd, dbh`` with a
    ``units`` attribute; ``shape`` as int8 codes with the attribute ``shape_names`` giving
    the name of each code; ``species`` as UTF-8 strings.
    """
    for name, unit in _UNITS.items():
        group.create_dataset(name, data=getattr(stand, name)).attrs["units"] = unit
    group.create_dataset("shape", data=stand.shape).attrs["shape_names"] = list(SHAPE_NAMES)
    group.create_dataset(
        "species", data=np.asarray(stand.species, dtype=object), dtype=h5py.string_dtype()
    )
    group.attrs["n_trees"] = stand.n_trees


def read_stand(group: h5py.Group) -> Stand:
    """Read a stand written by :func:`write_stand`; shape codes are remapped by name.

    Parameters
    ----------
    group : h5py.Group

    Returns
    -------
    Stand

    Raises
    ------
    ValueError
        Naming the missing datasets.
    """
    missing = [name for name in REQUIRED_COLUMNS if name not in group]
    if missing:
        raise ValueError(f"HDF5 group {group.name!r} lacks stand dataset(s) {missing}")
    columns = {name: group[name][()] for name in REQUIRED_COLUMNS if name != "shape"}
    stored_names = [str(n) for n in group["shape"].attrs.get("shape_names", SHAPE_NAMES)]
    codes = group["shape"][()]
    columns["shape"] = np.array([SHAPE_NAMES.index(stored_names[c]) for c in codes], np.int8)
    for name in OPTIONAL_COLUMNS:
        if name in group:
            data = group[name][()]
            if name == "species":
                data = np.array([v.decode() if isinstance(v, bytes) else v for v in data], object)
            columns[name] = data
    return Stand(**columns)


def save_stand(path, stand: Stand, group="stand") -> None:
    """Write a stand to an HDF5 file, replacing the group if present.

    Parameters
    ----------
    path : path
    stand : Stand
    group : str
    """
    with h5py.File(path, "a") as handle:
        if group in handle:
            del handle[group]
        write_stand(handle.create_group(group), stand)


def load_stand(path, group="stand") -> Stand:
    """Read a stand from an HDF5 file.

    Parameters
    ----------
    path : path
    group : str

    Returns
    -------
    Stand

    Raises
    ------
    ValueError
        Where the file has no such group.
    """
    with h5py.File(path, "r") as handle:
        if group not in handle:
            raise ValueError(f"{path}: no group {group!r}; groups are {list(handle)}")
        return read_stand(handle[group])
