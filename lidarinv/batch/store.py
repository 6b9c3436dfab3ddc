"""The results file of a batch inversion: one HDF5 file plus a summary CSV beside it.

Layout (``layout_version = 1``)::

    /                     attrs: content, layout_version, lidarinv_version, settings
                          (repr), inversion (function name), seed_entropy
    /shots/<shot_id>      one group per finished shot, written by ``result.write(group)``,
                          plus two attributes: ``batch`` (JSON: shot_id, index in the
                          input, attempts, seconds on the worker, worker, seed_key,
                          flags, finished_at (Unix time), summary = ``summary_row()``)
                          and ``batch_complete`` (set last)
    /failed/<shot_id>     one empty group per failed shot; attribute ``batch`` (JSON:
                          shot_id, index, attempts, reason, traceback)

Shot ids become group names through :func:`group_name` (``/`` is escaped). Only the
coordinating process opens the file; it is flushed after every shot, so an interrupted
run keeps every shot it finished, and a rerun skips them. A group left half-written by
an interruption lacks ``batch_complete`` and is redone.
"""

import csv
import json
import time
from pathlib import Path

import h5py
import numpy as np

import lidarinv

CONTENT = "lidarinv batch inversion results"
LAYOUT_VERSION = 1

#: CSV columns that come first; the result's summary keys follow.
BASE_COLUMNS = ("shot_id", "status", "reason", "attempts", "seconds", "flags")


def group_name(shot_id) -> str:
    """HDF5 group name of a shot id (``/`` escaped as ``%2F``, ``%`` as ``%25``).

    Integer-valued floats name the integer (``1.0`` → ``"1"``).
    """
    if isinstance(shot_id, float | np.floating) and float(shot_id).is_integer():
        shot_id = int(shot_id)  # an integer id that went through a float column
    name = str(shot_id).replace("%", "%25").replace("/", "%2F")
    if name in ("", ".", ".."):
        raise ValueError(f"shot id {shot_id!r} cannot name an HDF5 group")
    return name


def csv_path_for(path) -> Path:
    """The summary CSV that goes with a results file: same name, ``.csv`` suffix."""
    return Path(path).with_suffix(".csv")


def is_results_file(path) -> bool:
    """Whether ``path`` is a batch results file (one a run may resume)."""
    try:
        with h5py.File(path, "r") as handle:
            return handle.attrs.get("content") == CONTENT
    except OSError:
        return False


def is_summary_csv(path) -> bool:
    """Whether ``path`` looks like a summary CSV this module wrote (its header)."""
    try:
        with open(path, newline="") as handle:
            return handle.readline().startswith(f"{BASE_COLUMNS[0]},")
    except (OSError, UnicodeDecodeError):
        return False


def _scalar(value):
    """A JSON-able Python scalar from a NumPy or Python scalar."""
    if isinstance(value, np.generic):
        return value.item()
    return value


class ResultStore:
    """Append-mode access to a batch results file, used by the coordinating process.

    Parameters
    ----------
    path : str or Path
        HDF5 file; created if missing, resumed if it exists.
    settings_text : str
        A description of the inversion settings (their ``repr``).
    inversion : str
        Name of the inversion function (``module.qualname``). A file written by another
        inversion or with other settings is refused, so such results never mix.

    Raises
    ------
    ValueError
        If the file is not a batch results file or holds results of other settings.
    """

    def __init__(self, path, settings_text: str, inversion: str = ""):
        self.path = Path(path)
        self.file = h5py.File(self.path, "a")
        try:
            self._check_or_initialise(settings_text, inversion)
        except Exception:
            self.file.close()
            raise
        self.shots = self.file.require_group("shots")
        self.failed = self.file.require_group("failed")
        self._discard_incomplete()

    def _check_or_initialise(self, settings_text: str, inversion: str) -> None:
        attrs = self.file.attrs
        if "content" not in attrs:
            if len(self.file):
                raise ValueError(f"{self.path} is not a lidarinv batch results file")
            attrs["content"] = CONTENT
            attrs["layout_version"] = LAYOUT_VERSION
            attrs["lidarinv_version"] = lidarinv.__version__
            attrs["settings"] = settings_text
            attrs["inversion"] = inversion
            return
        if attrs["content"] != CONTENT:
            raise ValueError(f"{self.path} is not a lidarinv batch results file")
        if int(attrs["layout_version"]) != LAYOUT_VERSION:
            raise ValueError(f"{self.path}: unsupported layout version {attrs['layout_version']}")
        if str(attrs["settings"]) != settings_text:
            raise ValueError(
                f"{self.path} holds results of other inversion settings; write to a new "
                "file, or start afresh (lidarinv batch --overwrite)"
            )
        if str(attrs.get("inversion", "")) != inversion:
            raise ValueError(
                f"{self.path} holds results of another inversion "
                f"({attrs.get('inversion', '')!s}, not {inversion}); write to a new file"
            )

    def _discard_incomplete(self) -> None:
        for name in [k for k, g in self.shots.items() if not g.attrs.get("batch_complete")]:
            del self.shots[name]
        self.file.flush()

    # -- seeds -------------------------------------------------------------------------

    def seed_entropy(self, fresh: int) -> int:
        """The file's root seed entropy; ``fresh`` is stored and returned on first use."""
        if "seed_entropy" not in self.file.attrs:
            self.file.attrs["seed_entropy"] = str(fresh)
        return int(self.file.attrs["seed_entropy"])

    def set_seed_entropy(self, entropy: int) -> None:
        """Record the root seed entropy of this run (overwrites)."""
        self.file.attrs["seed_entropy"] = str(entropy)

    # -- queries -----------------------------------------------------------------------

    def is_done(self, shot_id) -> bool:
        """True if the shot has a complete result in the file."""
        return group_name(shot_id) in self.shots

    def __len__(self) -> int:
        return len(self.shots)

    # -- writing -----------------------------------------------------------------------

    def write_done(self, shot_id, result, *, index, attempts, seconds, worker, seed_key,
                   beam=None):  # fmt: skip
        """Store a finished shot: ``result.write(group)`` and the batch attributes (with
        the shot's ``beam`` where the format has beams)."""
        name = group_name(shot_id)
        if name in self.shots:
            del self.shots[name]
        group = self.shots.create_group(name)
        try:
            result.write(group)
            row = {key: _scalar(value) for key, value in result.summary_row().items()}
        except Exception:
            del self.shots[name]
            self.file.flush()
            raise
        record = {"shot_id": str(shot_id), "index": int(index), "attempts": int(attempts),
                  "seconds": float(seconds), "worker": str(worker), "seed_key": str(seed_key),
                  "flags": ";".join(str(f) for f in getattr(result, "flags", [])),
                  "finished_at": time.time(), "summary": row}  # fmt: skip
        if beam is not None:
            record["beam"] = str(beam)
        group.attrs["batch"] = json.dumps(record, default=str)  # one attribute: fast
        group.attrs["batch_complete"] = True
        if name in self.failed:
            del self.failed[name]
        self.file.flush()

    def write_failed(self, shot_id, reason, *, index, attempts, traceback_text="", beam=None):
        """Record a failed shot with its reason (replaces an earlier record)."""
        name = group_name(shot_id)
        if name in self.failed:
            del self.failed[name]
        group = self.failed.create_group(name)
        record = {"shot_id": str(shot_id), "index": int(index), "attempts": int(attempts),
                  "reason": str(reason), "traceback": str(traceback_text)}  # fmt: skip
        if beam is not None:
            record["beam"] = str(beam)
        group.attrs["batch"] = json.dumps(record)
        self.file.flush()

    # -- summary -----------------------------------------------------------------------

    def rows(self) -> list:
        """One dict per shot (finished and failed), in input order."""
        rows = []
        for group in self.shots.values():
            a = json.loads(group.attrs["batch"])
            row = {"shot_id": a["shot_id"], "beam": a.get("beam"), "status": "done",
                   "reason": "", "attempts": a["attempts"], "seconds": a["seconds"],
                   "flags": a["flags"]}  # fmt: skip
            row.update({k: v for k, v in a["summary"].items() if k not in BASE_COLUMNS})
            rows.append((a["index"], row))
        for group in self.failed.values():
            a = json.loads(group.attrs["batch"])
            row = {"shot_id": a["shot_id"], "beam": a.get("beam"), "status": "failed",
                   "reason": a["reason"], "attempts": a["attempts"], "seconds": "",
                   "flags": ""}  # fmt: skip
            rows.append((a["index"], row))
        rows.sort(key=lambda item: item[0])
        if all(row["beam"] is None for _, row in rows):  # a format without beams
            for _, row in rows:
                del row["beam"]
        return [row for _, row in rows]

    def write_csv(self, path=None) -> Path:
        """Write the summary CSV (one row per shot; the beam second, where the format has
        beams) and return its path."""
        path = csv_path_for(self.path) if path is None else Path(path)
        rows = self.rows()
        columns = list(BASE_COLUMNS)
        if any("beam" in row for row in rows):
            columns.insert(1, "beam")
        for row in rows:
            columns.extend(k for k in row if k not in columns)
        with open(path, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=columns, restval="")
            writer.writeheader()
            writer.writerows(rows)
        return path

    def close(self) -> None:
        if self.file.id.valid:
            self.file.flush()
            self.file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def read_result(path, shot_id, result_class):
    """Read one shot back: ``result_class.read`` on its group in a results file.

    Parameters
    ----------
    path : str or Path
        Results file written by :func:`lidarinv.batch.invert_many`.
    shot_id : int or str
        The shot.
    result_class : type
        Class with a ``read(group)`` classmethod (``InversionResult``).
    """
    with h5py.File(path, "r") as handle:
        name = group_name(shot_id)
        if name not in handle.get("shots", {}):
            raise KeyError(f"{path}: no finished result for shot {shot_id!r}")
        return result_class.read(handle["shots"][name])
