"""Output files of the command line: checked before any computation, never replaced
without ``--overwrite``, and written whole or not at all.

Every check raises a ``ValueError`` whose message names the file, so that a missing or
read-only folder is reported before a minute of sampling rather than after it.
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


def check_new_file(path, overwrite: bool, what="output") -> Path:
    """``path`` can be written and is not an existing file (unless ``overwrite``)."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"cannot write {what} {path}: it is a folder")
    if path.exists() and not overwrite:
        raise ValueError(
            f"{what} {path} exists; pass --overwrite to replace it, or choose another file"
        )
    return check_folder_writable(path, what)


def check_plot_folder(folder) -> Path:
    """A folder for figures: created if missing (its parent must exist), writable."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"cannot write figures to {folder}: it is a file")
    if not folder.exists():
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
