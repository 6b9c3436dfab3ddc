"""Output files of the command line: checked before any computation, never replaced
without ``--overwrite``, and written whole or not at all.

Every file a command writes (posterior files, metrics CSV and JSON, figures, batch results
and the summary CSV beside them) goes through :func:`check_new_files` (or, for groups of an
HDF5 file, :func:`check_hdf5_groups`) before any work. Every check raises a
``ValueError`` whose message names the file(s), so that a missing or read-only folder, or
a file that would be replaced, is reported before a minute of sampling rather than after
it.
"""

import contextlib
import os
import tempfile
from pathlib import Path

import h5py


def check_folder_writable(path, what="output") -> Path:
    """The folder of ``path`` exists and a file can be created in it.

    The test creates (and removes) a temporary file there, so it answers for the user
    who runs the command (``os.access`` does not, e.g. for root or on network shares).
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ValueError(f"cannot write {what} {path}: folder {folder} does not exist")
    try:
        handle, probe = tempfile.mkstemp(dir=folder, prefix=".lidarinv-probe-")
    except OSError as error:
        reason = error.strerror or type(error).__name__
        raise ValueError(f"cannot write {what} {path}: folder {folder}: {reason}") from None
    os.close(handle)
    os.unlink(probe)
    return path


def check_new_files(outputs, overwrite: bool) -> list:
    """Each ``(path, what)`` of ``outputs`` can be written and none is an existing file
    (unless ``overwrite``); one error names every file that would be replaced.

    Returns the paths.
    """
    outputs = [(Path(path), what) for path, what in outputs]
    for path, what in outputs:
        if path.is_dir():
            raise ValueError(f"cannot write {what} {path}: it is a folder")
    existing = [what if str(path) in what else f"{what} {path}" for path, what in outputs
                if path.exists()]  # fmt: skip
    if existing and not overwrite:
        many = len(existing) > 1
        shown = ", ".join(existing[:5]) + (f" and {len(existing) - 5} more" if many else "")
        raise ValueError(
            f"{shown} {'exist' if many else 'exists'}; pass --overwrite to replace "
            f"{'them' if many else 'it'}, or choose {'other files' if many else 'another file'}"
        )
    return [check_folder_writable(path, what) for path, what in outputs]


def check_new_file(path, overwrite: bool, what="output") -> Path:
    """``path`` can be written and is not an existing file (unless ``overwrite``)."""
    return check_new_files([(path, what)], overwrite)[0]


def check_plot_folder(folder, names=(), overwrite: bool = False, pattern=None) -> Path:
    """A folder for figures: created if missing (its parent must exist), writable, and
    holding none of the figures ``names`` (nor any file matching the glob ``pattern``:
    figures of an earlier run this one may replace), unless ``overwrite``."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"cannot write figures to {folder}: it is a file")
    if folder.is_dir():  # a new folder holds no figure to replace
        figures = [folder / name for name in names]
        if pattern is not None:
            figures += sorted(folder.glob(pattern))
        check_new_files([(path, "figure") for path in dict.fromkeys(figures)], overwrite)
    else:
        check_folder_writable(folder, "figure folder")
        folder.mkdir()
    check_folder_writable(folder / "figure.png", "figures in")
    return folder


def check_hdf5_groups(path, names, overwrite: bool, what="posterior file") -> Path:
    """``path`` is writable HDF5 (or can be created) and holds none of the groups
    ``names`` (unless ``overwrite``)."""
    path = check_folder_writable(path, what)
    if not path.exists():
        return path
    try:
        with h5py.File(path, "r+") as handle:
            present = [name for name in names if name in handle]
    except OSError as error:
        raise ValueError(
            f"cannot write {what} {path}: not a writable HDF5 file ({error})"
        ) from None
    if present and not overwrite:
        raise ValueError(
            f"{what} {path} already holds {', '.join(present)}; pass --overwrite to replace "
            "it, or write to another file with -o"
        )
    return path


def save_group(path, name, write) -> None:
    """Write one group of an HDF5 file whole: ``write(group)`` fills a temporary group,
    which then replaces ``name``. Interrupted or failed, it leaves the file as it was
    (and no file at all where there was none)."""
    path = Path(path)
    existed = path.exists()
    partial = f"{name}.partial"
    try:
        with h5py.File(path, "a") as handle:
            if partial in handle:
                del handle[partial]
            write(handle.create_group(partial))
            if name in handle:
                del handle[name]
            handle.move(partial, name)
    except BaseException:
        _discard_group(path, partial, existed)
        raise


def _discard_group(path, partial, existed) -> None:
    with contextlib.suppress(OSError):
        if not existed:
            path.unlink()
            return
        with h5py.File(path, "a") as handle:
            if partial in handle:
                del handle[partial]


@contextlib.contextmanager
def written_whole(path):
    """Yield a temporary path beside ``path``; on success it becomes ``path`` (an atomic
    rename), on an error or an interruption it is removed and ``path`` is untouched."""
    path = Path(path)
    handle, temporary = tempfile.mkstemp(
        dir=path.parent or ".", prefix=f".{path.stem}.", suffix=path.suffix
    )
    os.close(handle)
    temporary = Path(temporary)
    try:
        yield temporary
        os.replace(temporary, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            temporary.unlink()
