"""Batch inversion of many footprints, on local processes, any executor, or Dask.

>>> from lidarinv.batch import invert_many                      # doctest: +SKIP
>>> summary = invert_many(iter_observations("L1B.h5"), settings, output="results.h5")

See :func:`invert_many` for the options and :mod:`lidarinv.batch.store` for the layout
of the results file.
"""

from .executors import THREAD_ENV, connect_dask
from .runner import BatchSummary, invert_many, shot_seed_key
from .store import ResultStore, csv_path_for, group_name, read_result

__all__ = [
    "THREAD_ENV",
    "BatchSummary",
    "ResultStore",
    "connect_dask",
    "csv_path_for",
    "group_name",
    "invert_many",
    "read_result",
    "shot_seed_key",
]
