"""Readers for the NASA products to compare with: GEDI L2A and L2B (HDF5), LVIS L2 (text).

Each returns ``{shot_number: record}``, a record being a dict of the product's values for
one shot (elevations and heights in m, RH as an array indexed by percent), so that a
shot's direct metrics or posterior can be set beside the product's.
"""

import h5py
import numpy as np

#: GEDI L2A datasets read per shot.
GEDI_L2A_FIELDS = (
    "elev_lowestmode",
    "elev_highestreturn",
    "rh",
    "quality_flag",
    "degrade_flag",
    "sensitivity",
    "num_detectedmodes",
    "selected_algorithm",
    "lat_lowestmode",
    "lon_lowestmode",
)
#: GEDI L2B datasets read per shot.
GEDI_L2B_FIELDS = (
    "cover",
    "pai",
    "cover_z",
    "pai_z",
    "pavd_z",
    "l2b_quality_flag",
    "rhov",
    "rhog",
    "rossg",
    "omega",
    "pgap_theta",
)
#: LVIS L2 columns: LFID SHOTNUMBER TIME GLON GLAT ZG TLON TLAT ZT RH10 … RH100 and the rest.
LVIS_L2_RH = (*range(10, 96, 5), 96, 97, 98, 99, 100)
LVIS_L2_COLUMNS = (
    "lfid", "shot_number", "time", "glon", "glat", "zg", "tlon", "tlat", "zt",
    *(f"rh{p}" for p in LVIS_L2_RH), "azimuth", "incident_angle", "range",
    "flag1", "flag2", "flag3",
)  # fmt: skip
#: Value LVIS L2 uses for a missing metric.
LVIS_MISSING = -999.0


def _gedi_product(path, fields, short_name) -> dict:
    out = {}
    with h5py.File(path, "r") as handle:
        beams = sorted(k for k in handle if k.startswith("BEAM"))
        if not beams:
            raise ValueError(f"{path}: no BEAMxxxx groups; not a GEDI {short_name} file")
        for beam in beams:
            group = handle[beam]
            shots = group["shot_number"][()]
            values = {name: group[name][()] for name in fields if name in group}
            for i, shot in enumerate(shots):
                record = {"beam": beam, **{name: column[i] for name, column in values.items()}}
                out[int(shot)] = {
                    k: v.item() if isinstance(v, np.generic) else v for k, v in record.items()
                }
    return out


def read_gedi_l2a(path) -> dict:
    """GEDI L2A elevation and height metrics per shot number (``rh`` has 101 values)."""
    return _gedi_product(path, GEDI_L2A_FIELDS, "L2A")


def read_gedi_l2b(path) -> dict:
    """GEDI L2B cover and vertical profile per shot number (``pavd_z`` in 5 m layers)."""
    return _gedi_product(path, GEDI_L2B_FIELDS, "L2B")


def read_lvis_l2(path) -> dict:
    """LVIS L2 ground and height metrics per shot number.

    ``zg`` is the ground (the lowest mode), ``zt`` the highest return (m); ``rh`` is an
    array of 101 values in m above ``zg``, NaN at the percentiles the product does not
    give (below 10, between its 5 % steps) or marks missing (−999).
    """
    table = np.loadtxt(path, ndmin=2)
    if table.shape[1] != len(LVIS_L2_COLUMNS):
        raise ValueError(
            f"{path}: {table.shape[1]} columns, expected {len(LVIS_L2_COLUMNS)} of LVIS L2"
        )
    out = {}
    for row in table:
        record = dict(zip(LVIS_L2_COLUMNS, row.tolist()))
        rh = np.full(101, np.nan)
        for p in LVIS_L2_RH:
            value = record.pop(f"rh{p}")
            rh[p] = np.nan if value == LVIS_MISSING else value
        record["rh"] = rh
        for key in ("zg", "zt"):
            if record[key] == LVIS_MISSING:
                record[key] = np.nan
        record["lfid"] = int(record["lfid"])
        out[int(record.pop("shot_number"))] = record
    return out
