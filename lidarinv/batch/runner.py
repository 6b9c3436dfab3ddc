"""Invert many shots: stream observations to workers, store results, survive failures."""

import hashlib
import time
import warnings
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lidarinv.observe.observation import ShotError

from .executors import is_transient, make_backend, short_reason
from .progress import ProgressBar
from .store import ResultStore, group_name


@dataclass
class BatchSummary:
    """What :func:`invert_many` did.

    Attributes
    ----------
    output, csv : Path
        The results file and its summary CSV.
    n_done, n_failed, n_skipped : int
        Shots inverted in this run, shots that failed in this run (unreadable shots
        included), and shots skipped because the file already held them (or because
        their id repeated an earlier shot of the input).
    seconds : float
        Wall time of the run.
    failed : dict
        Shot id (as named in the file, see :func:`~lidarinv.batch.store.group_name`) →
        reason, for the shots that failed in this run.
    stopped_early : bool
        True if ``max_shots`` stopped the run before the input was exhausted.
    beams : dict
        Shot id → beam, for the failed shots of a format with beams.
    """

    output: Path
    csv: Path | None = None
    n_done: int = 0
    n_failed: int = 0
    n_skipped: int = 0
    seconds: float = 0.0
    failed: dict = field(default_factory=dict)
    stopped_early: bool = False
    beams: dict = field(default_factory=dict)

    @property
    def shots_per_second(self) -> float:
        """Finished shots per second of wall time in this run."""
        return self.n_done / self.seconds if self.seconds > 0 else float("nan")

    def __str__(self) -> str:
        text = (
            f"{self.n_done} done, {self.n_failed} failed, {self.n_skipped} skipped in "
            f"{self.seconds:.1f} s ({self.shots_per_second:.2f} shots/s)"
        )
        if self.stopped_early:
            text += "; stopped at max_shots, rerun to continue"
        return text


@dataclass
class _Task:
    index: int
    shot_id: object
    observation: object
    seed: np.random.SeedSequence
    seed_key: str
    attempts: int = 0
    generation: int = 0
    alone: bool = False


def beam_of(item):
    """The beam of a shot (an Observation or a ShotError), None for formats without."""
    beam = getattr(item, "metadata", {}).get("beam")
    return None if beam is None else str(beam)


def shot_seed_key(shot_id) -> int:
    """A stable 64-bit key of a shot id (the same in every run and process)."""
    digest = hashlib.blake2b(group_name(shot_id).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little")


def _root_entropy(rng, store: ResultStore) -> int:
    """Root seed entropy of the run from ``rng`` (or the file's, when resuming)."""
    if rng is None:
        return store.seed_entropy(np.random.SeedSequence().entropy)
    if isinstance(rng, np.random.Generator):
        entropy = int.from_bytes(rng.bytes(16), "little")
    elif isinstance(rng, np.random.SeedSequence):
        if rng.spawn_key:
            raise ValueError("pass a root SeedSequence (no spawn_key) or a Generator")
        entropy = int(rng.entropy)
    elif isinstance(rng, int | np.integer) and not isinstance(rng, bool) and rng >= 0:
        entropy = int(rng)
    else:
        raise TypeError(f"rng must be a Generator, SeedSequence, int ≥ 0 or None, not {rng!r}")
    store.set_seed_entropy(entropy)
    return entropy


def default_invert():
    try:
        from lidarinv.inference import invert_shot
    except ImportError as error:
        raise ImportError(
            f"the default inversion lidarinv.inference.invert_shot is not available ({error}); "
            "pass invert=..."
        ) from error
    return invert_shot


def _callable_name(function) -> str:
    """``module.qualname`` of a function (of the class, for a callable object)."""
    function = getattr(function, "func", function)  # functools.partial
    named = function if hasattr(function, "__qualname__") else type(function)
    return f"{named.__module__}.{named.__qualname__}"


class _Source:
    """Turns the input stream into tasks: records unreadable shots, skips finished ones."""

    def __init__(self, observations, store, entropy, max_shots, summary, bar):
        self._iter = iter(observations)
        self._store, self._entropy, self._max = store, entropy, max_shots
        self._summary, self._bar = summary, bar
        self._index, self._new = 0, 0
        self.in_flight = set()  # group names of shots submitted and not yet finished
        self.exhausted = False

    def next(self):
        """The next shot to invert, or None at the end of the input (or at max_shots)."""
        while not self.exhausted:
            if self._max is not None and self._new >= self._max:
                self._summary.stopped_early = self._peek_more()
                self.exhausted = True
                break
            try:
                item = next(self._iter)
            except StopIteration:
                self.exhausted = True
                break
            index, self._index = self._index, self._index + 1
            name = group_name(item.shot_id)
            if name in self.in_flight or self._store.is_done(item.shot_id):
                if name in self.in_flight:
                    warnings.warn(f"shot id {item.shot_id!r} repeats; skipped", stacklevel=3)
                self._summary.n_skipped += 1
                self._bar.skipped()
                continue
            if isinstance(item, ShotError):
                reason = f"unreadable: {item.reason}"
                beam = beam_of(item)
                self._store.write_failed(item.shot_id, reason, index=index, attempts=0,
                                         beam=beam)  # fmt: skip
                self._summary.n_failed += 1
                self._summary.failed[name] = reason
                if beam is not None:
                    self._summary.beams[name] = beam
                self._bar.unreadable()
                continue
            self._new += 1
            self._bar.started()
            self.in_flight.add(name)
            key = shot_seed_key(item.shot_id)
            seed = np.random.SeedSequence(self._entropy, spawn_key=(key,))
            return _Task(index, item.shot_id, item, seed, f"{self._entropy}/{key}")
        return None

    def _peek_more(self) -> bool:
        """Whether input remains (consumes one item; only used when stopping)."""
        try:
            next(self._iter)
        except StopIteration:
            return False
        return True

    def close(self):
        close = getattr(self._iter, "close", None)
        if close is not None:
            close()


def invert_many(
    observations,
    settings=None,
    *,
    output,
    executor=None,
    workers=None,
    invert=None,
    rng=None,
    progress=True,
    retries=1,
    max_shots=None,
    total=None,
) -> BatchSummary:
    """Invert many shots in parallel into one resumable HDF5 file and a summary CSV.

    Parameters
    ----------
    observations : iterable of Observation or ShotError
        The shots, e.g. ``lidarinv.io.iter_observations(path)``; consumed lazily, with at
        most 2 × workers shots in flight. A ShotError is recorded as failed with its
        reason. Shot ids must be unique: a repeat of a shot that is in flight or stored
        is skipped (with a warning when in flight).
    settings : object, optional
        Inversion settings (``InversionSettings``; picklable). The local pool and Dask
        hand them to each worker once; a generic executor gets them with every task.
    output : str or Path
        Results file (HDF5; layout in :mod:`lidarinv.batch.store`). If it exists, shots
        it already holds are skipped; it must have been written by the same inversion
        function with equal settings (same ``repr``). The CSV is written next to it
        (``.csv`` suffix).
    executor : None, concurrent.futures.Executor or dask.distributed.Client
        None: a local process pool of ``workers`` processes (rebuilt if a worker dies).
        An executor is used as given and not shut down.
    workers : int, optional
        Local pool size (default the CPU count); with an executor or a Dask client, the
        number of workers it has (default: its own count), which sets the bound on
        shots in flight.
    invert : callable, optional
        ``invert(observation, settings, rng=Generator, progress=False) -> result``;
        default ``lidarinv.inference.invert_shot``. Must be importable by the workers
        (a module-level function). The result must be picklable and have
        ``summary_row()``, ``write(group)`` and ``flags``.
    rng : numpy.random.Generator, SeedSequence, int or None
        Root of the per-shot seeds. Each shot gets
        ``SeedSequence(root_entropy, spawn_key=(hash(shot_id),))``, so its result does
        not depend on scheduling, on the number of workers or on which other shots are
        in the run. None: fresh entropy, or the entropy stored in an existing file.
    progress : bool
        Show a tqdm progress bar (shots/s, ETA, done/failed/skipped counts).
    retries : int
        Further attempts after a shot meets an error of its environment (an ``OSError``,
        ``MemoryError`` or ``TimeoutError``: :data:`.executors.TRANSIENT_ERRORS`) or its
        worker process dies; then it is recorded as failed (reason: the exception's
        short form) and the batch goes on. Any other error is recorded at once: a
        shot's inversion depends only on its observation, the settings and its seed, so
        it would fail again (e.g. a ground outside the window).
        When a local worker dies the pool is rebuilt and the shots that were in flight
        run again one at a time, so the shot that killed it is identified and the others
        are not charged. On Dask the scheduler reruns the tasks of a lost worker itself
        (``distributed.scheduler.allowed-failures``); a shot it gives up on
        (``KilledWorker``) is recorded as failed at once.
    max_shots : int, optional
        Stop after this many new shots (skipped and unreadable shots do not count);
        rerun to continue.
    total : int, optional
        Number of input shots (default ``len(observations)`` when it has one). The
        progress bar's total and ETA count only the shots the run will process: at most
        ``max_shots``, and not those the file already holds.

    Returns
    -------
    BatchSummary

    Notes
    -----
    Only this (the coordinating) process writes the file; it is flushed after every
    shot, and the CSV is regenerated from the file at the end, also after an error or
    an interruption. Local workers start with ``OMP_NUM_THREADS`` etc. set to 1 (see
    :mod:`lidarinv.batch.executors` for Dask and other executors).
    """
    if retries < 0:
        raise ValueError(f"retries must be ≥ 0, got {retries}")
    if max_shots is not None and max_shots < 0:
        raise ValueError(f"max_shots must be ≥ 0, got {max_shots}")
    invert = default_invert() if invert is None else invert
    if total is None and hasattr(observations, "__len__"):
        total = len(observations)
    start = time.perf_counter()
    summary = BatchSummary(output=Path(output))
    store = ResultStore(output, repr(settings), _callable_name(invert))
    bar = backend = source = None
    try:
        bar = ProgressBar(total=total, enabled=progress, cap=max_shots)
        source = _Source(observations, store, _root_entropy(rng, store), max_shots, summary, bar)
        backend = make_backend(executor, workers, invert, settings)
        _run(source, backend, store, summary, bar, retries)
        backend.close()
        backend = None
    finally:
        if backend is not None:
            backend.close(cancel=True)
        if source is not None:
            source.close()
        if bar is not None:
            bar.close()
        summary.seconds = time.perf_counter() - start
        summary.csv = store.write_csv()
        store.close()
    return summary


def _run(source, backend, store, summary, bar, retries) -> None:
    pending = {}  # future → task
    retry, suspects = deque(), deque()

    def submit(task, alone=False):
        task.alone = alone
        future = backend.submit(task.observation, task.seed)
        task.generation = backend.generation
        pending[future] = task

    def fill():
        if suspects:  # after a crash: suspects run alone, so a culprit is identified
            if not pending:
                submit(suspects.popleft(), alone=True)
            return
        while len(pending) < backend.capacity:
            task = retry.popleft() if retry else source.next()
            if task is None:
                return
            submit(task)

    def fail(task, reason, text=""):
        name, beam = group_name(task.shot_id), beam_of(task.observation)
        source.in_flight.discard(name)
        store.write_failed(task.shot_id, reason, index=task.index, attempts=task.attempts,
                           traceback_text=text, beam=beam)  # fmt: skip
        summary.n_failed += 1
        summary.failed[name] = reason
        if beam is not None:
            summary.beams[name] = beam
        bar.advance("failed")

    while True:
        fill()
        if not pending:
            return
        for future in backend.wait(list(pending)):
            task = pending.pop(future)
            task.attempts += 1
            error = future.exception()
            if error is None:
                try:
                    outcome = future.result()
                except Exception as lost:  # it finished, but its result died with its worker
                    if task.attempts <= retries:
                        retry.append(task)
                    else:
                        fail(task, f"result lost with its worker ({short_reason(lost)})")
                    continue
                if outcome.reason == "":
                    try:
                        store.write_done(task.shot_id, outcome.result, index=task.index,
                                         attempts=task.attempts, seconds=outcome.seconds,
                                         worker=outcome.worker, seed_key=task.seed_key,
                                         beam=beam_of(task.observation))  # fmt: skip
                    except Exception as write_error:  # a result that cannot be stored
                        fail(task, f"could not store the result: {short_reason(write_error)}")
                        continue
                    source.in_flight.discard(group_name(task.shot_id))
                    summary.n_done += 1
                    bar.advance("done")
                elif outcome.transient and task.attempts <= retries:
                    retry.append(task)
                else:
                    fail(task, outcome.reason, outcome.traceback)
                continue
            crash = backend.crash_kind(error)
            if crash == "pool":
                if task.generation == backend.generation:
                    backend.rebuild()
                # a shot that shared the pool may be innocent: it always gets a run alone
                if not task.alone or task.attempts <= retries:
                    suspects.append(task)
                else:
                    fail(task, f"worker process died ({type(error).__name__})")
            elif crash == "lost":
                fail(task, f"worker lost ({type(error).__name__}: {str(error).split(',')[0]})")
            elif is_transient(error) and task.attempts <= retries:
                retry.append(task)
            else:
                fail(task, f"{type(error).__name__}: {error}")
