"""Explicit stands: a stem map with one crown per tree."""

import csv
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .crowns import SHAPE_NAMES, crown_volume, shape_codes

REQUIRED_COLUMNS = ("x", "y", "height", "crown_length", "crown_radius", "shape", "favd")
OPTIONAL_COLUMNS = ("dbh", "species")


@dataclass(frozen=True)
class Stand:
    """A stem map of trees with crowns of uniform foliage density.

    Parameters
    ----------
    x, y : array (m)
        Stem positions.
    height : array (m)
        Tree height; the crown top is at ``height``.
    crown_length : array (m)
        Vertical crown extent; the crown base is at ``height - crown_length``.
    crown_radius : array (m)
        Horizontal crown radius.
    shape : array of int8
        Crown-shape codes, indices into :data:`forward.crowns.SHAPE_NAMES`. Use
        :meth:`Stand.from_arrays` to pass shape names.
    favd : array (m²/m³)
        Foliage area volume density inside each crown.
    dbh : array (cm), optional
        Diameter at breast height, NaN where unknown.
    species : array of str, optional
        Species label, empty where unknown.
    """

    x: np.ndarray
    y: np.ndarray
    height: np.ndarray
    crown_length: np.ndarray
    crown_radius: np.ndarray
    shape: np.ndarray
    favd: np.ndarray
    dbh: np.ndarray = field(default=None)
    species: np.ndarray = field(default=None)

    def __post_init__(self):
        n = np.asarray(self.x).shape[0] if np.ndim(self.x) else 0
        floats = ("x", "y", "height", "crown_length", "crown_radius", "favd")
        for name in floats:
            object.__setattr__(self, name, np.atleast_1d(np.asarray(getattr(self, name), float)))
        object.__setattr__(self, "shape", np.atleast_1d(np.asarray(self.shape, np.int8)))
        dbh = np.full(n, np.nan) if self.dbh is None else np.atleast_1d(np.asarray(self.dbh, float))
        species = (
            np.full(n, "", dtype=object)
            if self.species is None
            else np.atleast_1d(np.asarray(self.species, dtype=object))
        )
        object.__setattr__(self, "dbh", dbh)
        object.__setattr__(self, "species", species)
        self._validate()

    def _validate(self):
        arrays = {name: getattr(self, name) for name in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS)}
        lengths = {name: a.shape for name, a in arrays.items()}
        n = arrays["x"].shape
        if any(a.ndim != 1 for a in arrays.values()) or any(s != n for s in lengths.values()):
            raise ValueError(
                f"stand columns must be 1-D arrays of one length, got shapes {lengths}"
            )
        for name in ("x", "y", "height", "crown_length", "crown_radius", "favd"):
            bad = ~np.isfinite(arrays[name])
            if bad.any():
                raise ValueError(
                    f"stand column {name!r} has non-finite values at rows {_rows(bad)}"
                )
        for name in ("height", "crown_length", "crown_radius", "favd"):
            bad = arrays[name] < 0
            if bad.any():
                raise ValueError(f"stand column {name!r} has negative values at rows {_rows(bad)}")
        too_long = self.crown_length > self.height
        if too_long.any():
            raise ValueError(
                f"crown_length exceeds height (crown below the ground) at rows {_rows(too_long)}"
            )
        bad_shape = (self.shape < 0) | (self.shape >= len(SHAPE_NAMES))
        if bad_shape.any():
            raise ValueError(f"unknown crown-shape codes at rows {_rows(bad_shape)}")

    # construction -------------------------------------------------------------------
    @classmethod
    def from_arrays(cls, *, shape="ellipsoid", **columns):
        """Build a stand from keyword arrays.

        Parameters
        ----------
        shape : str or array
            Shape names (or codes), or one name for all trees.
        **columns
            ``x``, ``y``, ``height``, ``crown_length``, ``crown_radius`` (m), ``favd``
            (m²/m³, one value or one per tree), optional ``dbh`` (cm) and ``species``.

        Returns
        -------
        Stand
        """
        n = np.size(columns["x"])
        shapes = np.broadcast_to(np.asarray(shape), (n,)) if np.ndim(shape) == 0 else shape
        favd = np.asarray(columns.pop("favd"), float)
        if favd.ndim and favd.shape != (n,):
            raise ValueError(
                f"favd must be one number or one value per tree ({n}), got shape {favd.shape}"
            )
        favd = np.broadcast_to(favd, (n,))
        is_named = np.asarray(shapes).dtype.kind in "USO"
        codes = shape_codes(shapes) if is_named else np.asarray(shapes, np.int8)
        return cls(shape=codes, favd=favd.copy(), **columns)

    @classmethod
    def empty(cls):
        """A stand without trees (a bare-ground scene).

        Returns
        -------
        Stand
        """
        return cls(*(np.zeros(0) for _ in range(5)), shape=np.zeros(0, np.int8), favd=np.zeros(0))

    @classmethod
    def from_csv(cls, path):
        """Read a stem map from CSV.

        Parameters
        ----------
        path : path
            Columns ``x, y, height, crown_length, crown_radius, shape, favd`` are required,
            ``dbh`` and ``species`` optional; lengths in m, FAVD in m²/m³, DBH in cm; lines
            starting with ``#`` are comments.

        Returns
        -------
        Stand

        Raises
        ------
        ValueError
            Naming the file and the problem.
        """
        path = Path(path)
        with path.open(newline="") as handle:
            reader = csv.DictReader(row for row in handle if not row.lstrip().startswith("#"))
            header = [name.strip() for name in (reader.fieldnames or [])]
            missing = [name for name in REQUIRED_COLUMNS if name not in header]
            if missing:
                raise ValueError(f"{path}: missing column(s) {missing}; found {header}")
            rows = [{k.strip(): (v or "").strip() for k, v in row.items()} for row in reader]
        columns = {}
        for name in ("x", "y", "height", "crown_length", "crown_radius", "favd", "dbh"):
            if name in header:
                columns[name] = _parse_floats(path, name, [row[name] for row in rows])
        if "species" in header:
            columns["species"] = np.array([row["species"] for row in rows], dtype=object)
        try:
            codes = shape_codes([row["shape"] for row in rows])
        except ValueError as error:
            raise ValueError(f"{path}: {error}") from None
        try:
            return cls(shape=codes, **columns)
        except ValueError as error:
            raise ValueError(f"{path}: {error}") from None

    def to_csv(self, path):
        """Write the stem map as CSV (the layout :meth:`from_csv` reads).

        Parameters
        ----------
        path : path
        """
        with Path(path).open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow((*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS))
            for i in range(self.n_trees):
                writer.writerow(
                    (
                        *(repr(float(getattr(self, c)[i])) for c in REQUIRED_COLUMNS[:5]),
                        SHAPE_NAMES[self.shape[i]],
                        repr(float(self.favd[i])),
                        repr(float(self.dbh[i])),
                        self.species[i],
                    )
                )

    # derived quantities -----------------------------------------------------------------
    @property
    def n_trees(self) -> int:
        return int(self.x.shape[0])

    @property
    def shape_names(self) -> np.ndarray:
        return np.array(SHAPE_NAMES, dtype=object)[self.shape]

    @property
    def crown_base(self) -> np.ndarray:
        """Crown base height (m)."""
        return self.height - self.crown_length

    @property
    def crown_volume(self) -> np.ndarray:
        """Crown volume of each tree (m³)."""
        return crown_volume(self.shape, self.crown_radius, self.crown_length)

    @property
    def leaf_area(self) -> np.ndarray:
        """One-sided foliage area of each tree (m²): FAVD times crown volume."""
        return self.favd * self.crown_volume

    def subset(self, index) -> "Stand":
        """The trees selected by a boolean mask or an index array.

        Parameters
        ----------
        index : array of bool or int

        Returns
        -------
        Stand
        """
        return replace(self, **{n: getattr(self, n)[index] for n in _ALL_COLUMNS})

    def translated(self, dx, dy) -> "Stand":
        """The same stand moved.

        Parameters
        ----------
        dx, dy : float (m)

        Returns
        -------
        Stand
        """
        return replace(self, x=self.x + dx, y=self.y + dy)

    def with_shape(self, name) -> "Stand":
        """The same stand with every crown given one shape (the paper's Fig. 6 and 10).

        Parameters
        ----------
        name : str

        Returns
        -------
        Stand
        """
        return replace(self, shape=shape_codes(np.full(self.n_trees, name)))

    def with_favd(self, favd) -> "Stand":
        """The same stand with its FAVD replaced.

        Parameters
        ----------
        favd : float or array (m²/m³)

        Returns
        -------
        Stand
        """
        return replace(self, favd=np.broadcast_to(np.asarray(favd, float), (self.n_trees,)).copy())


_ALL_COLUMNS = (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS)


def _rows(mask, limit=5):
    rows = np.flatnonzero(mask)
    text = ", ".join(str(r) for r in rows[:limit])
    return text + (f", … ({rows.size} in all)" if rows.size > limit else "")


def _parse_floats(path, name, values):
    out = np.empty(len(values))
    for i, value in enumerate(values):
        try:
            out[i] = float(value) if value != "" else np.nan
        except ValueError:
            raise ValueError(
                f"{path}: column {name!r} row {i}: {value!r} is not a number"
            ) from None
    return out
