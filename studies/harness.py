"""What the studies share: one thread each, the common options, the output folder and
the machine-readable summary.

A study is run as a script from the repository (``python studies/NAME.py``), so this
module is importable beside it as ``harness``; the test suite finds it the same way
(``pythonpath`` in pyproject.toml). It holds no numerical code.
"""

import argparse
import json
import os
from pathlib import Path

#: Where every study writes: ``studies/output/<name><tag>/``.
OUTPUT = Path(__file__).resolve().parent / "output"

#: Threading libraries held to one thread: a study's timings are per core, and studies
#: running side by side share the machine.
THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMBA_NUM_THREADS",
)


def pin_threads() -> None:
    """Hold numpy's BLAS, OpenMP and numba to one thread. Call it before numpy is first
    imported (the libraries read these variables when they load)."""
    for name in THREAD_VARIABLES:
        os.environ[name] = "1"


def parser(doc: str, *, seed: int | None = None, tag: bool = True,
           workers: int | None = None) -> argparse.ArgumentParser:  # fmt: skip
    """A study's command line, with the options studies share.

    Parameters
    ----------
    doc : str
        The study's module docstring: its first line describes the command.
    seed : int, optional
        Default of ``--seed`` (the study's random generator); no option if None.
    tag : bool
        Add ``--tag``, the suffix of the output folder (runs kept side by side).
    workers : int, optional
        Default of ``--workers`` (processes); no option if None.

    Returns
    -------
    argparse.ArgumentParser
    """
    out = argparse.ArgumentParser(description=doc.strip().splitlines()[0])
    if seed is not None:
        out.add_argument("--seed", type=int, default=seed, help=f"random seed (default {seed})")
    if tag:
        out.add_argument("--tag", default="", help="suffix of the output folder")
    if workers is not None:
        out.add_argument("--workers", type=int, default=workers, help="processes")
    return out


def output_folder(name: str, tag: str = "") -> Path:
    """``studies/output/<name><tag>``, made if missing."""
    folder = OUTPUT / f"{name}{tag}"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _plain(value):
    """numpy scalars and arrays as JSON numbers and lists."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def write_json(path, data, indent: int = 1) -> Path:
    """Write a study's summary (or records) as JSON; numpy values become plain numbers.

    Parameters
    ----------
    path : path
    data : dict or list
    indent : int

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    path.write_text(json.dumps(data, indent=indent, default=_plain) + "\n")
    return path
