"""Batch inversion: process pool, any executor, Dask, resume, failures, killed workers, CLI.

All tests use the fake inversion of ``lidarinv/testing/fake_inversion.py`` (importable by worker
processes); the real single-shot inversion is not needed.
"""

import csv
import json
import threading
from concurrent.futures import Future, ProcessPoolExecutor, ThreadPoolExecutor

import h5py
import numpy as np
import pytest

from lidarinv.batch import ResultStore, invert_many, read_result
from lidarinv.cli import main
from lidarinv.io import write_observations
from lidarinv.testing.fake_inversion import FakeResult, FakeSettings, fake_invert, fake_observations


def _observations(n, errors=()):
    return list(fake_observations(n, np.random.default_rng(42), errors=errors))


def _csv(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _medians(rows):
    return {r["shot_id"]: r["height_median"] for r in rows if r["status"] == "done"}


class _Recorder:
    """A thread-safe wrapper of the fake that records which shots it was called for."""

    def __init__(self):
        self.calls, self._lock = [], threading.Lock()

    def __call__(self, observation, settings=None, *, rng=None, progress=False):
        with self._lock:
            self.calls.append(str(observation.shot_id))
        return fake_invert(observation, settings, rng=rng, progress=progress)


def test_process_pool_batch_writes_every_shot_and_matches_threads(tmp_path):
    obs = _observations(8, errors={2})
    settings = FakeSettings(fail=frozenset({"5"}), payload=np.zeros(1000))
    out = tmp_path / "pool.h5"
    summary = invert_many(obs, settings, output=out, workers=2, invert=fake_invert, rng=7,
                          progress=False)  # fmt: skip
    assert (summary.n_done, summary.n_failed, summary.n_skipped) == (6, 2, 0)
    assert summary.failed["2"].startswith("unreadable: fake unreadable shot")
    assert "ValueError: shot 5: fake failure" in summary.failed["5"]
    rows = _csv(summary.csv)
    assert [r["shot_id"] for r in rows] == [str(i) for i in range(8)]  # one row per shot
    status = {r["shot_id"]: (r["status"], r["attempts"]) for r in rows}
    # a ValueError (the shot's data) would repeat with the same seed: one attempt only
    assert status["5"] == ("failed", "1") and status["2"] == ("failed", "0")
    assert status["0"] == ("done", "1")
    with h5py.File(out, "r") as handle:
        assert sorted(handle["shots"]) == ["0", "1", "3", "4", "6", "7"]
        assert sorted(handle["failed"]) == ["2", "5"]
        assert "fake_invert" in json.loads(handle["failed/5"].attrs["batch"])["traceback"]
    back = read_result(out, 3, FakeResult)
    assert back.samples.shape == (settings.n_samples, 2)

    # any Executor: threads give the same per-shot numbers (seeds follow the shot ids)
    with ThreadPoolExecutor(max_workers=3) as pool:
        again = invert_many(obs[::-1], settings, output=tmp_path / "threads.h5", executor=pool,
                            invert=fake_invert, rng=7, progress=False)  # fmt: skip
    assert again.n_done == 6
    assert _medians(_csv(again.csv)) == _medians(rows)


def test_seed_changes_results_and_is_kept_on_resume(tmp_path):
    obs = _observations(4)
    with ThreadPoolExecutor(2) as pool:
        a = invert_many(obs, output=tmp_path / "a.h5", executor=pool, invert=fake_invert,
                        rng=np.random.default_rng(1), progress=False)  # fmt: skip
        b = invert_many(obs, output=tmp_path / "b.h5", executor=pool, invert=fake_invert,
                        rng=np.random.default_rng(2), progress=False)  # fmt: skip
    assert _medians(_csv(a.csv)) != _medians(_csv(b.csv))


def test_resume_after_interruption_skips_finished_shots(tmp_path):
    obs = _observations(12)
    out = tmp_path / "resume.h5"

    def interrupted():
        yield from obs[:7]
        raise RuntimeError("reader died")

    first = _Recorder()
    with ThreadPoolExecutor(2) as pool, pytest.raises(RuntimeError, match="reader died"):
        invert_many(interrupted(), output=out, executor=pool, invert=first, rng=3,
                    progress=False)  # fmt: skip
    with h5py.File(out, "r") as handle:
        kept = set(handle["shots"])
    assert kept and kept <= set(first.calls)
    assert len(_csv(tmp_path / "resume.csv")) == len(kept)  # CSV written on the way out

    second = _Recorder()
    with ThreadPoolExecutor(2) as pool:
        summary = invert_many(obs, output=out, executor=pool, invert=second, progress=False)
    assert summary.n_skipped == len(kept) and summary.n_done == 12 - len(kept)
    assert not kept & set(second.calls)
    assert len(_csv(summary.csv)) == 12

    # the resumed run reused the stored seed: same numbers as an uninterrupted run
    with ThreadPoolExecutor(2) as pool:
        whole = invert_many(obs, output=tmp_path / "whole.h5", executor=pool,
                            invert=fake_invert, rng=3, progress=False)  # fmt: skip
    assert _medians(_csv(whole.csv)) == _medians(_csv(summary.csv))


def test_max_shots_then_rerun_completes(tmp_path):
    obs = _observations(7)
    out = tmp_path / "max.h5"
    with ThreadPoolExecutor(2) as pool:
        part = invert_many(obs, output=out, executor=pool, invert=fake_invert, rng=0,
                           max_shots=3, progress=False)  # fmt: skip
        assert part.n_done == 3 and part.stopped_early
        rest = invert_many(obs, output=out, executor=pool, invert=fake_invert, rng=0,
                           progress=False)  # fmt: skip
    assert (rest.n_done, rest.n_skipped, rest.stopped_early) == (4, 3, False)


def test_failing_shot_is_retried_then_recorded(tmp_path):
    obs = _observations(6)
    # an error of the environment (OSError) is retried
    settings = FakeSettings(fail=frozenset({"1", "4"}), fail_with="OSError", once_dir=str(tmp_path))
    with ThreadPoolExecutor(2) as pool:
        summary = invert_many(obs, settings, output=tmp_path / "r.h5", executor=pool,
                              invert=fake_invert, progress=False)  # fmt: skip
    assert summary.n_done == 6  # each failed once, then succeeded on its retry
    attempts = {r["shot_id"]: r["attempts"] for r in _csv(summary.csv)}
    assert attempts["1"] == attempts["4"] == "2" and attempts["0"] == "1"

    # an error of the shot's data would repeat (same shot, same seed): not retried
    data = FakeSettings(fail=frozenset({"1"}), once_dir=str(tmp_path / "data"))
    (tmp_path / "data").mkdir()
    with ThreadPoolExecutor(2) as pool:
        summary = invert_many(obs, data, output=tmp_path / "v.h5", executor=pool,
                              invert=fake_invert, retries=3, progress=False)  # fmt: skip
    assert summary.n_done == 5 and list(summary.failed) == ["1"]
    assert {r["shot_id"]: r["attempts"] for r in _csv(summary.csv)}["1"] == "1"

    always = FakeSettings(fail=frozenset({"4"}))
    with ThreadPoolExecutor(2) as pool:
        summary = invert_many(obs, always, output=tmp_path / "f.h5", executor=pool,
                              invert=fake_invert, retries=0, progress=False)  # fmt: skip
    assert summary.n_done == 5 and list(summary.failed) == ["4"]
    assert _csv(summary.csv)[4]["reason"].startswith("ValueError: shot 4: fake failure")


def test_killed_worker_loses_only_its_shot(tmp_path):
    obs = _observations(6)
    settings = FakeSettings(crash=frozenset({"2"}))
    summary = invert_many(obs, settings, output=tmp_path / "k.h5", workers=2,
                          invert=fake_invert, progress=False)  # fmt: skip
    assert summary.n_done == 5
    assert summary.failed == {"2": "worker process died (BrokenProcessPool)"}
    rows = {r["shot_id"]: r for r in _csv(summary.csv)}
    assert len(rows) == 6 and rows["2"]["status"] == "failed"


def test_broken_user_process_pool_falls_back_to_a_local_pool(tmp_path):
    obs = _observations(4)
    settings = FakeSettings(crash=frozenset({"1"}))
    with ProcessPoolExecutor(2) as pool, pytest.warns(RuntimeWarning, match="executor broke"):
        summary = invert_many(obs, settings, output=tmp_path / "u.h5", executor=pool,
                              invert=fake_invert, progress=False)  # fmt: skip
    assert summary.n_done == 3 and list(summary.failed) == ["1"]


def test_dask_local_cluster(tmp_path):
    distributed = pytest.importorskip("distributed")
    import dask

    obs = _observations(6)
    settings = FakeSettings(crash=frozenset({"4"}))
    # the scheduler gives up on a shot after its first lost worker
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                      dashboard_address=None) as cluster:  # fmt: skip
            with distributed.Client(cluster) as client:
                summary = invert_many(obs, settings, output=tmp_path / "d.h5", executor=client,
                                      invert=fake_invert, rng=5, progress=False)  # fmt: skip
    # the crash loses shot 4; a shot queued on the same worker may be lost with it (the
    # scheduler allows no failures here), never anything else
    assert summary.n_done + len(summary.failed) == 6 and summary.n_done >= 4
    assert "4" in summary.failed
    assert all(reason.startswith("worker lost (KilledWorker") for reason in summary.failed.values())
    with ThreadPoolExecutor(2) as pool:
        local = invert_many(obs, output=tmp_path / "t.h5", executor=pool, invert=fake_invert,
                            rng=5, progress=False)  # fmt: skip
    expected = {k: v for k, v in _medians(_csv(local.csv)).items() if k not in summary.failed}
    done = {k: v for k, v in _medians(_csv(summary.csv)).items() if k not in summary.failed}
    assert done == expected


class _LosesFirstResult(ThreadPoolExecutor):
    """A pool whose first shot finishes but whose result is then lost, as a Dask result is
    when its worker dies between the task's end and the gather."""

    def __init__(self):
        super().__init__(2)
        self.lost = 0

    def submit(self, fn, *args, **kwargs):
        inner = super().submit(fn, *args, **kwargs)
        if self.lost:
            return inner
        self.lost += 1
        outer = _LostResult()
        inner.add_done_callback(lambda done: outer.set_result(done.result()))
        return outer


class _LostResult(Future):
    def result(self, timeout=None):
        raise RuntimeError("its worker died before the result was gathered")


@pytest.mark.parametrize("retries", [0, 1])
def test_a_result_lost_after_its_shot_finished_is_retried_not_fatal(tmp_path, retries):
    obs = _observations(3)
    with _LosesFirstResult() as pool:
        summary = invert_many(obs, output=tmp_path / "l.h5", executor=pool, invert=fake_invert,
                              rng=5, progress=False, retries=retries)  # fmt: skip
    assert summary.n_done + len(summary.failed) == 3
    if retries:
        assert summary.n_done == 3 and not summary.failed
    else:
        [reason] = summary.failed.values()
        assert reason.startswith("result lost with its worker")


def test_store_refuses_other_settings_and_redoes_half_written_shots(tmp_path):
    out = tmp_path / "s.h5"
    obs = _observations(3)
    with ThreadPoolExecutor(1) as pool:
        invert_many(obs, FakeSettings(delay=0.0), output=out, executor=pool,
                    invert=fake_invert, progress=False)  # fmt: skip
        with pytest.raises(ValueError, match="other inversion settings"):
            invert_many(obs, FakeSettings(delay=0.5), output=out, executor=pool,
                        invert=fake_invert, progress=False)  # fmt: skip
        with h5py.File(out, "a") as handle:
            del handle["shots/1"].attrs["batch_complete"]  # as if killed mid-write
        with pytest.raises(ValueError, match="another inversion"):
            invert_many(obs, FakeSettings(delay=0.0), output=out, executor=pool,
                        invert=_Recorder(), progress=False)  # fmt: skip
        name = "lidarinv.testing.fake_inversion.fake_invert"
        with ResultStore(out, repr(FakeSettings(delay=0.0)), name) as store:
            assert not store.is_done(1) and store.is_done(0)
        again = invert_many(obs, FakeSettings(delay=0.0), output=out, executor=pool,
                            invert=fake_invert, progress=False)  # fmt: skip
    assert (again.n_done, again.n_skipped) == (1, 2)


def test_cli_batch(tmp_path, capsys):
    path = tmp_path / "obs.h5"
    write_observations(path, _observations(5))
    out = tmp_path / "cli.h5"
    args = ["batch", str(path), "-o", str(out), "--workers", "1", "--no-progress",
            "--invert", "lidarinv.testing.fake_inversion:fake_invert", "--seed", "4"]  # fmt: skip
    assert main([*args, "--shot", "1", "--shot", "3"]) == 0
    assert "2 done, 0 failed, 0 skipped" in capsys.readouterr().out
    assert main(args) == 0
    assert "3 done, 0 failed, 2 skipped" in capsys.readouterr().out
    assert len(_csv(tmp_path / "cli.csv")) == 5
    assert main(["batch", str(path), "-o", str(out), "--invert", "nowhere:nothing"]) == 2
    assert "--invert nowhere:nothing" in capsys.readouterr().err
    priors = ["--priors", str(tmp_path / "missing.toml")]
    assert main(["batch", str(path), "-o", str(out), *priors]) == 2
    assert "priors" in capsys.readouterr().err


def test_cli_batch_on_a_dask_scheduler(tmp_path, capsys):
    distributed = pytest.importorskip("distributed")
    from lidarinv.batch import connect_dask

    path = tmp_path / "obs.h5"
    write_observations(path, _observations(4))
    out = tmp_path / "sched.h5"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:  # fmt: skip
        args = ["batch", str(path), "-o", str(out), "--scheduler", cluster.scheduler_address,
                "--no-progress", "--invert", "lidarinv.testing.fake_inversion:fake_invert"]  # fmt: skip
        assert main(args) == 0
    assert "4 done, 0 failed, 0 skipped" in capsys.readouterr().out
    assert len(_csv(tmp_path / "sched.csv")) == 4
    with pytest.raises(ValueError, match=r"no Dask scheduler answered at tcp://127\.0\.0\.1:9"):
        connect_dask("tcp://127.0.0.1:9", timeout=1.0)
