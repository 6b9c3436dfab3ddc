"""Where shots run: a local process pool, any ``concurrent.futures.Executor``, or Dask.

Each backend hands the inversion function and its settings to the workers once where it
can (a pool initializer; ``client.scatter(..., broadcast=True)`` on Dask) and then submits
one small task per shot: the observation and its seed. The task (:func:`run_task`)
catches exceptions raised by the inversion and returns them as a :class:`TaskOutcome`
with a short reason, so that only infrastructure failures (a dead worker process) reach
the coordinator as exceptions.

Threads per worker: numerical libraries must not start one thread per core in every
worker. The local pool starts its worker processes (``spawn``) with ``OMP_NUM_THREADS``,
``OPENBLAS_NUM_THREADS`` and ``MKL_NUM_THREADS`` set to 1 in their environment, so the
limits hold before NumPy is imported there. Dask's nanny sets the same variables before
it starts a worker (``distributed.nanny.pre-spawn-environ``); the Dask task sets them
where they are missing, which only helps libraries that read them later (a library
already loaded keeps its thread pool: the limitation of setting them inside a task).
A user-supplied executor is used as it is: its workers keep their thread settings.

Orphans: a local worker ends itself when the coordinator dies, even by ``SIGKILL`` (a
scheduler's or a timeout's), which gives it no chance to stop its pool: each worker
watches its parent's pid from a daemon thread (:func:`watch_parent`, every
:data:`PARENT_POLL_S`; portable, unlike Linux's ``PR_SET_PDEATHSIG``, which would also
fire when the thread that started the worker ends).
"""

import concurrent.futures as cf
import multiprocessing
import os
import signal
import socket
import threading
import time
import traceback
import warnings
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

#: Environment that keeps each worker process on one thread.
THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


# -- what runs on a worker ---------------------------------------------------------------


@dataclass
class TaskOutcome:
    """What a worker sends back for one shot.

    Parameters
    ----------
    result : object or None
        The inversion result; None if the inversion raised.
    seconds : float
        Wall time of the inversion on the worker.
    worker : str
        ``host:pid`` of the worker process.
    reason : str
        Short form of the exception (type, message, innermost frame); empty on success.
    traceback : str
        Full traceback text; empty on success.
    transient : bool
        Whether the error came from the environment (:data:`TRANSIENT_ERRORS`), so that
        another attempt may succeed; any other error repeats, since a shot's inversion
        is a function of its observation, settings and seed alone.
    """

    result: object
    seconds: float
    worker: str
    reason: str = ""
    traceback: str = ""
    transient: bool = False


#: Errors of the environment (files, memory, network) that another attempt may not meet.
#: Every other exception of an inversion is certain to repeat: a retry reruns the same
#: computation on the same observation with the same seed.
TRANSIENT_ERRORS = (OSError, MemoryError, TimeoutError)


def is_transient(error: BaseException) -> bool:
    """Whether another attempt after ``error`` may succeed (see :data:`TRANSIENT_ERRORS`)."""
    return isinstance(error, TRANSIENT_ERRORS)


def short_reason(error: BaseException) -> str:
    """``Type: message (file.py:line in function)`` for an exception."""
    text = f"{type(error).__name__}: {error}"
    frames = traceback.extract_tb(error.__traceback__)
    if frames:
        last = frames[-1]
        text += f" ({os.path.basename(last.filename)}:{last.lineno} in {last.name})"
    return text


def run_task(invert, observation, settings, seed) -> TaskOutcome:
    """Invert one shot; exceptions become a failed :class:`TaskOutcome`.

    Parameters
    ----------
    invert : callable
        ``invert(observation, settings, rng=Generator, progress=False)``.
    observation : Observation
        The shot.
    settings : object
        Passed to ``invert``.
    seed : numpy.random.SeedSequence
        The shot's seed; the inversion gets ``numpy.random.default_rng(seed)``.
    """
    worker = f"{socket.gethostname()}:{os.getpid()}"
    start = time.perf_counter()
    try:
        result = invert(observation, settings, rng=np.random.default_rng(seed), progress=False)
    except Exception as error:
        return TaskOutcome(None, time.perf_counter() - start, worker, short_reason(error),
                           traceback.format_exc(), is_transient(error))  # fmt: skip
    return TaskOutcome(result, time.perf_counter() - start, worker)


_SHARED = {}

#: Seconds between a worker's checks that its coordinator is alive.
PARENT_POLL_S = 0.5

#: Exit status of a worker whose coordinator died.
ORPHAN_EXIT = 75


def watch_parent(parent: int, interval: float = PARENT_POLL_S) -> threading.Thread:
    """End this process (``os._exit``) as soon as its parent is no longer ``parent``: the
    coordinator died and the worker was handed to another process.

    Parameters
    ----------
    parent : int
        Pid of the coordinator that started this process.
    interval : float (s)
        Time between checks.

    Returns
    -------
    threading.Thread
        The daemon thread that watches.
    """

    def watch():
        while os.getppid() == parent:
            time.sleep(interval)
        os._exit(ORPHAN_EXIT)

    thread = threading.Thread(target=watch, name="lidarinv-parent-watch", daemon=True)
    thread.start()
    return thread


def init_worker(invert, settings, parent=None) -> None:
    """Process-pool initializer: one thread per library, shared data stored once; Ctrl-C
    is left to the coordinator, which stops the workers (no traceback from each); the
    worker ends when the coordinator ``parent`` (a pid) dies."""
    if parent is not None:
        watch_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ.update(THREAD_ENV)
    # tqdm would create a multiprocessing lock here, which a worker ended by Ctrl-C
    # could not release (a "leaked semaphore" warning); the workers draw no bars
    from tqdm import tqdm

    tqdm.set_lock(threading.RLock())
    _SHARED["invert"], _SHARED["settings"] = invert, settings


@dataclass(frozen=True)
class WithFlag:
    """An inversion whose every result carries one more warning ``flag`` (e.g. that the
    user overrode the file's instrument); picklable where ``invert`` is.

    Parameters
    ----------
    invert : callable
        ``invert(observation, settings, rng=..., progress=...)``.
    flag : str
        Appended to ``result.flags``.
    """

    invert: object
    flag: str

    def __call__(self, observation, settings=None, *, rng=None, progress=False):
        result = self.invert(observation, settings, rng=rng, progress=progress)
        result.flags.append(self.flag)
        return result


def _run_shared(observation, seed) -> TaskOutcome:
    """Task of the local pool: the inversion and settings come from the initializer."""
    return run_task(_SHARED["invert"], observation, _SHARED["settings"], seed)


def _run_dask(invert, observation, settings, seed) -> TaskOutcome:
    """Task on a Dask worker (``settings`` arrives resolved from the scattered future)."""
    for key, value in THREAD_ENV.items():
        os.environ.setdefault(key, value)
    return run_task(invert, observation, settings, seed)


@contextmanager
def _thread_env():
    """Set :data:`THREAD_ENV` in this process while worker processes are started."""
    saved = {key: os.environ.get(key) for key in THREAD_ENV}
    os.environ.update(THREAD_ENV)
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


# -- backends on the coordinator ----------------------------------------------------------


class ProcessBackend:
    """The embedded default: a ``ProcessPoolExecutor`` that is rebuilt after a crash.

    Parameters
    ----------
    workers : int
        Worker processes.
    invert, settings
        Handed to each worker once through the pool initializer.
    """

    def __init__(self, workers: int, invert, settings):
        if workers < 1:
            raise ValueError(f"need at least one worker, got {workers}")
        self.workers = workers
        self.capacity = 2 * workers
        self.generation = 0
        self._initargs = (invert, settings)
        self._pool = self._new_pool()

    def _new_pool(self):
        return cf.ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=init_worker,
            initargs=(*self._initargs, os.getpid()),
        )

    def submit(self, observation, seed):
        with _thread_env():  # worker processes inherit it when they start
            try:
                return self._pool.submit(_run_shared, observation, seed)
            except cf.BrokenExecutor:
                self.rebuild()
                return self._pool.submit(_run_shared, observation, seed)

    def crash_kind(self, error) -> str | None:
        """``"pool"`` if the error means the pool broke (a worker died), else None."""
        return "pool" if isinstance(error, cf.BrokenExecutor) else None

    def rebuild(self) -> None:
        """Replace a broken pool by a fresh one."""
        self._pool.shutdown(wait=False, cancel_futures=True)
        self._pool = self._new_pool()
        self.generation += 1

    @staticmethod
    def wait(futures):
        return cf.wait(futures, return_when=cf.FIRST_COMPLETED).done

    def close(self, cancel: bool = False) -> None:
        """Shut the pool down; with ``cancel`` (an error or an interruption on the
        coordinator) the shots in flight are abandoned and the workers ended at once."""
        if cancel:
            processes = list((getattr(self._pool, "_processes", None) or {}).values())
            for process in processes:
                process.terminate()
            for process in processes:
                process.join(timeout=5)
        # after the workers ended, the pool sees them gone and releases its queues
        self._pool.shutdown(wait=True, cancel_futures=cancel)


class ExecutorBackend:
    """Any ``concurrent.futures.Executor`` given by the caller (not shut down here).

    The settings travel with every task, since a generic executor has no initializer.
    If the executor breaks (a process pool whose worker died), the rest of the batch
    runs on a fresh local :class:`ProcessBackend`.

    Parameters
    ----------
    executor : concurrent.futures.Executor
        The caller's executor.
    workers : int, optional
        Its number of workers (sets the bound on shots in flight); default the
        executor's ``_max_workers`` or the CPU count.
    invert, settings
        The inversion and its settings.
    """

    def __init__(self, executor, workers, invert, settings):
        self.executor = executor
        self.workers = workers or getattr(executor, "_max_workers", None) or os.cpu_count()
        self.capacity = 2 * self.workers
        self.generation = 0
        self._invert, self._settings = invert, settings
        self._fallback = None

    def submit(self, observation, seed):
        if self._fallback is not None:
            return self._fallback.submit(observation, seed)
        try:
            return self.executor.submit(run_task, self._invert, observation, self._settings, seed)
        except cf.BrokenExecutor:
            self.rebuild()
            return self._fallback.submit(observation, seed)

    def crash_kind(self, error) -> str | None:
        return "pool" if isinstance(error, cf.BrokenExecutor) else None

    def rebuild(self) -> None:
        if self._fallback is not None:
            self._fallback.rebuild()
        else:
            warnings.warn(
                "the executor broke (a worker process died); continuing on a local "
                f"process pool of {self.workers} workers",
                RuntimeWarning,
                stacklevel=2,
            )
            self._fallback = ProcessBackend(self.workers, self._invert, self._settings)
        self.generation += 1

    @staticmethod
    def wait(futures):
        return cf.wait(futures, return_when=cf.FIRST_COMPLETED).done

    def close(self, cancel: bool = False) -> None:
        if self._fallback is not None:
            self._fallback.close(cancel)


class DaskBackend:
    """A ``dask.distributed.Client``: settings scattered once to every worker.

    A worker that dies is handled by the scheduler, which reruns its tasks elsewhere up
    to ``distributed.scheduler.allowed-failures`` times and then reports
    ``KilledWorker``; such a shot is recorded as failed without a further retry here.

    Parameters
    ----------
    client : dask.distributed.Client
        Connected client.
    workers : int, optional
        Sets the bound on shots in flight (2 × workers); default the cluster's total
        number of worker threads.
    invert, settings
        The inversion and its settings.
    """

    def __init__(self, client, workers, invert, settings):
        self.client = client
        total = sum(client.nthreads().values())
        self.workers = workers or total or 1
        self.capacity = 2 * self.workers
        self.generation = 0
        self._invert = invert
        [self._settings] = client.scatter([settings], broadcast=True, hash=False)

    def submit(self, observation, seed):
        return self.client.submit(_run_dask, self._invert, observation, self._settings, seed,
                                  pure=False)  # fmt: skip

    @staticmethod
    def crash_kind(error) -> str | None:
        """``"lost"`` for ``KilledWorker`` (the scheduler gave up on the shot), else None."""
        return "lost" if type(error).__name__ == "KilledWorker" else None

    def rebuild(self) -> None:  # the scheduler replaces lost workers itself
        self.generation += 1

    @staticmethod
    def wait(futures):
        from distributed import wait

        return wait(futures, return_when="FIRST_COMPLETED").done

    def close(self, cancel: bool = False) -> None:
        self.client.cancel([self._settings])


def _is_dask_client(executor) -> bool:
    module = type(executor).__module__ or ""
    return module.startswith("distributed") and hasattr(executor, "scatter")


def make_backend(executor, workers, invert, settings):
    """The backend for ``executor``: None → local pool; Executor; Dask client.

    Raises
    ------
    TypeError
        For anything else.
    """
    if executor is None:
        return ProcessBackend(workers or os.cpu_count() or 1, invert, settings)
    if _is_dask_client(executor):
        return DaskBackend(executor, workers, invert, settings)
    if isinstance(executor, cf.Executor):
        return ExecutorBackend(executor, workers, invert, settings)
    raise TypeError(
        "executor must be None, a concurrent.futures.Executor or a dask.distributed.Client, "
        f"not {type(executor).__name__}"
    )


def connect_dask(address: str, timeout: float = 20.0):
    """A ``dask.distributed.Client`` connected to ``address`` (dask is optional).

    Parameters
    ----------
    address : str
        The scheduler, e.g. ``tcp://host:8786``.
    timeout : float (s)
        How long to try to reach it.

    Raises
    ------
    ImportError
        With installation advice when ``dask.distributed`` is missing.
    ValueError
        When no scheduler answers at ``address`` within ``timeout``.
    """
    try:
        from distributed import Client
    except ImportError as error:
        raise ImportError(
            "running on a Dask cluster needs dask.distributed: pip install 'lidarinv[distributed]'"
        ) from error
    try:
        return Client(address, timeout=timeout)
    except (OSError, TimeoutError) as error:
        raise ValueError(
            f"no Dask scheduler answered at {address} within {timeout:g} s ({error})"
        ) from None
