"""A batch killed with SIGKILL (as a scheduler or a timeout does) leaves no worker running."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from lidarinv.io import write_observations
from lidarinv.testing.fake_inversion import PID_FOLDER, fake_observations

ROOT = Path(__file__).resolve().parents[3]


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, ended but not yet reaped, does not)."""
    try:
        with open(f"/proc/{pid}/stat") as handle:
            return handle.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False
    except OSError:  # no /proc: ask the kernel
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


def _wait_for(condition, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.1)
    return condition()


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL is POSIX")
def test_workers_end_when_a_batch_is_killed(tmp_path):
    path = tmp_path / "obs.h5"
    write_observations(path, list(fake_observations(4, np.random.default_rng(1))))
    pids = tmp_path / "pids"
    pids.mkdir()
    env = {**os.environ, PID_FOLDER: str(pids)}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    command = [sys.executable, "-c", "import sys; from lidarinv.cli import main; sys.exit(main())",
               "batch", str(path), "-o", str(tmp_path / "r.h5"), "--workers", "2",
               "--no-progress", "--invert", "lidarinv.testing.fake_inversion:sleepy_invert"]  # fmt: skip
    batch = subprocess.Popen(command, cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE)  # fmt: skip
    workers = []
    try:
        started = _wait_for(lambda: len(list(pids.iterdir())) == 2 or batch.poll() is not None, 120)
        assert started and batch.poll() is None, batch.stderr.read().decode()
        workers = [int(p.name) for p in pids.iterdir()]
        assert all(_alive(pid) for pid in workers)
        batch.send_signal(signal.SIGKILL)
        batch.wait(timeout=10)
        survivors = lambda: [pid for pid in workers if _alive(pid)]
        assert _wait_for(lambda: not survivors(), 10), f"workers {survivors()} outlived the batch"
    finally:
        if batch.poll() is None:
            batch.kill()
        for pid in workers:  # never leave one behind, even when the test fails
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        batch.stderr.close()
