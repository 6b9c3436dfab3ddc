"""A stand-in for the single-shot inversion, for tests and overhead measurements.

:func:`fake_invert` has the signature of ``lidarinv.inference.invert_shot`` and returns a
:class:`FakeResult` with the same interface as ``InversionResult`` (``shot_id``,
``converged``, ``flags``, ``summary_row()``, ``write(group)``, ``read(group)``). Its numbers
are derived from the waveform and the per-shot random generator, so a batch run can be
checked for reproducibility. :class:`FakeSettings` can make chosen shots raise, or kill
the process that runs them, to exercise the batch runner's failure handling.

Everything here lives at module level so that process pools and Dask workers can unpickle
it.
"""

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lidarinv.observe.observation import Observation, ShotError

#: Exceptions :class:`FakeSettings` can make a shot raise, by name.
FAKE_ERRORS = {"ValueError": ValueError, "OSError": OSError, "MemoryError": MemoryError}


@dataclass(frozen=True)
class FakeSettings:
    """Behaviour of :func:`fake_invert`.

    Parameters
    ----------
    delay : float (s)
        Time each shot takes (``time.sleep``).
    fail : frozenset of str
        Shot ids (as strings) whose inversion raises ``fail_with``.
    fail_with : str
        The exception those shots raise, a name of :data:`FAKE_ERRORS`: ``ValueError``
        stands for an error of the shot's data (not retried), ``OSError`` for one of
        the environment (retried).
    crash : frozenset of str
        Shot ids whose inversion ends its process at once with ``os._exit``.
    once_dir : str, optional
        If given, ``fail`` and ``crash`` act only on a shot's first attempt: a marker file
        in this folder remembers that the shot has been tried (it works across
        processes).
    n_samples : int
        Number of fake posterior samples per shot.
    payload : array, optional
        Ballast standing for large shared data (model tables); unused.
    """

    delay: float = 0.0
    fail: frozenset = frozenset()
    fail_with: str = "ValueError"
    crash: frozenset = frozenset()
    once_dir: str | None = None
    n_samples: int = 64
    payload: np.ndarray | None = field(default=None, compare=False)


@dataclass
class FakeResult:
    """The result of :func:`fake_invert`, shaped like ``InversionResult``.

    Parameters
    ----------
    shot_id : int or str
        Shot identifier.
    converged : bool
        Always True for the fake.
    flags : list of str
        Warnings (``"weak signal"`` when the waveform barely rises above its median).
    samples : array, shape (n, 2)
        Fake posterior samples of ``height`` and ``cover``.
    n_steps : int
        Fake number of sampler steps.
    """

    shot_id: object
    converged: bool
    flags: list
    samples: np.ndarray
    n_steps: int

    NAMES = ("height", "cover")

    def summary_row(self) -> dict:
        """Flat scalar summary: shot id, convergence, steps, and percentiles per name."""
        row = {"shot_id": self.shot_id, "converged": bool(self.converged), "n_steps": self.n_steps}
        for j, name in enumerate(self.NAMES):
            p05, p16, p50, p84, p95 = np.percentile(self.samples[:, j], [5, 16, 50, 84, 95])
            row.update({f"{name}_median": float(p50), f"{name}_p05": float(p05),
                        f"{name}_p16": float(p16), f"{name}_p84": float(p84),
                        f"{name}_p95": float(p95)})  # fmt: skip
        return row

    def write(self, group) -> None:
        """Write the result into an open ``h5py.Group``."""
        group.attrs["shot_id"] = str(self.shot_id)
        group.attrs["converged"] = bool(self.converged)
        group.attrs["flags"] = ";".join(self.flags)
        group.attrs["n_steps"] = int(self.n_steps)
        group.create_dataset("samples", data=self.samples, chunks=True, compression="gzip")

    @classmethod
    def read(cls, group) -> "FakeResult":
        """Read a result written by :meth:`write`."""
        flags = str(group.attrs["flags"])
        return cls(
            shot_id=str(group.attrs["shot_id"]),
            converged=bool(group.attrs["converged"]),
            flags=flags.split(";") if flags else [],
            samples=np.asarray(group["samples"]),
            n_steps=int(group.attrs["n_steps"]),
        )


def _first_attempt(settings: FakeSettings, key: str) -> bool:
    """True the first time a shot is seen (always True without ``once_dir``)."""
    if settings.once_dir is None:
        return True
    marker = Path(settings.once_dir) / f"tried-{key}"
    try:
        marker.touch(exist_ok=False)
    except FileExistsError:
        return False
    return True


def fake_invert(observation, settings=None, *, rng=None, progress=False) -> FakeResult:
    """Pretend to invert one shot.

    Parameters
    ----------
    observation : Observation
        The shot.
    settings : FakeSettings, optional
        Delay and failure behaviour; default no delay, no failures.
    rng : numpy.random.Generator, optional
        Source of the fake posterior samples; a fixed default keeps calls reproducible.
    progress : bool
        Ignored (the real inversion may show a progress bar).

    Returns
    -------
    FakeResult

    Raises
    ------
    ValueError or OSError
        For shots listed in ``settings.fail`` (``settings.fail_with``).
    """
    settings = FakeSettings() if settings is None else settings
    rng = np.random.default_rng(0) if rng is None else rng
    key = str(observation.shot_id)
    if key in settings.crash and _first_attempt(settings, f"crash-{key}"):
        os._exit(3)
    if key in settings.fail and _first_attempt(settings, f"fail-{key}"):
        raise FAKE_ERRORS[settings.fail_with](f"shot {key}: fake failure")
    if settings.delay > 0:
        time.sleep(settings.delay)
    samples = np.asarray(observation.samples, float)
    contrast = float(samples.max() - np.median(samples))
    top = float(observation.axis[np.argmax(samples)])
    draws = rng.normal(size=(settings.n_samples, 2)) * [1.0, 0.05] + [top, 0.5]
    flags = ["weak signal"] if contrast < 1.0 else []
    return FakeResult(shot_id=observation.shot_id, converged=True, flags=flags,
                      samples=draws, n_steps=1000)  # fmt: skip


def fake_observations(n: int, rng: np.random.Generator, *, n_bins: int = 120, errors=()):
    """Simple synthetic observations (a canopy bump and a ground peak over noise).

    Parameters
    ----------
    n : int
        Number of shots; ids are ``0 … n-1``.
    rng : numpy.random.Generator
        Source of the heights and the noise.
    n_bins : int
        Bins per waveform (1 m each).
    errors : collection of int
        Shot ids yielded as :class:`ShotError` (unreadable shots) instead.

    Yields
    ------
    Observation or ShotError
    """
    axis = np.arange(n_bins, dtype=float) - 10.0
    for shot in range(n):
        if shot in errors:
            yield ShotError(shot, "fake unreadable shot", {})
            continue
        height = rng.uniform(10.0, 40.0)
        canopy = 20.0 * np.exp(-0.5 * ((axis - 0.7 * height) / (0.2 * height)) ** 2)
        ground = 50.0 * np.exp(-0.5 * (axis / 2.0) ** 2)
        samples = 5.0 + canopy + ground + rng.normal(0.0, 1.0, n_bins)
        yield Observation(samples=samples, axis=axis, shot_id=shot, noise_mean=5.0,
                          noise_sigma=1.0)  # fmt: skip


#: Environment variable naming the folder where :func:`sleepy_invert` leaves its pid.
PID_FOLDER = "LIDARINV_TEST_WORKER_PIDS"


def sleepy_invert(observation, settings=None, *, rng=None, progress=False):
    """An inversion that leaves its worker's pid in the folder :data:`PID_FOLDER` names,
    then sleeps far longer than any test (to kill its batch while it works)."""
    (Path(os.environ[PID_FOLDER]) / str(os.getpid())).touch()
    time.sleep(300)
