"""The command line protects a user's work: outputs checked before any computation, no
result replaced without --overwrite, errors that name the file, values refused by the
parser, failures reported in the exit status, Ctrl-C leaving no partial file."""

import os
from pathlib import Path

import h5py
import numpy as np
import pytest
from tiny_results import tiny_result

import lidarinv.inference
from lidarinv.cli import build_parser, main
from lidarinv.cli.batch import batch_settings
from lidarinv.cli.options import inversion_settings
from lidarinv.cli.outputs import save_group
from lidarinv.inference import InversionResult
from lidarinv.io import write_observations
from lidarinv.testing.fake_inversion import fake_observations

INVERT_EXAMPLE = ["invert", "--example", "gedi-mixed", "--quiet"]


@pytest.fixture(autouse=True)
def warm_kernels(monkeypatch):
    """The sampler is faked here: no compilation notice (tested on its own)."""
    monkeypatch.setattr("lidarinv.cli.kernels.cold_kernels", lambda: [])


@pytest.fixture
def fake_inversion(monkeypatch):
    """Replace the sampler by an instant one and count its calls."""
    calls = []

    def invert(observation, settings=None, *, rng=None, progress=False, **_):
        calls.append(observation.shot_id)
        return tiny_result(observation.shot_id)

    monkeypatch.setattr(lidarinv.inference, "invert_shot", invert)
    return calls


def _read_only_folder(tmp_path) -> Path:
    folder = tmp_path / "read-only"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        (folder / "probe").touch()
    except OSError:
        return folder
    (folder / "probe").unlink()  # root writes anywhere: a folder even root cannot write
    for candidate in (Path("/sys"), Path("/proc")):
        try:
            (candidate / "lidarinv-probe").touch()
        except OSError:
            return candidate
    pytest.skip("no read-only folder on this machine")


# -- outputs checked before any computation -------------------------------------------


def test_invert_refuses_a_missing_or_read_only_folder_before_sampling(
    tmp_path, capsys, fake_inversion
):
    for folder in (tmp_path / "missing", _read_only_folder(tmp_path)):
        out = folder / "post.h5"
        assert main([*INVERT_EXAMPLE, "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert str(out) in err and "cannot write" in err
    assert fake_inversion == []  # nothing was sampled


def test_invert_never_replaces_a_posterior_without_overwrite(tmp_path, capsys, fake_inversion):
    out = tmp_path / "post.h5"
    assert main([*INVERT_EXAMPLE, "-o", str(out)]) == 0
    first = InversionResult.load(out, "shot_gedi-mixed").samples.copy()
    capsys.readouterr()
    assert main([*INVERT_EXAMPLE, "-o", str(out), "--seed", "3"]) == 2
    err = capsys.readouterr().err
    assert str(out) in err and "shot_gedi-mixed" in err and "--overwrite" in err
    assert len(fake_inversion) == 1  # refused before the second run sampled
    np.testing.assert_array_equal(InversionResult.load(out, "shot_gedi-mixed").samples, first)
    assert main([*INVERT_EXAMPLE, "-o", str(out), "--overwrite"]) == 0
    with h5py.File(out) as handle:
        assert list(handle) == ["shot_gedi-mixed"]  # replaced, no partial group left


def test_invert_prints_the_footprint_quantities_first(tmp_path, capsys, fake_inversion):
    assert main([*INVERT_EXAMPLE, "-o", str(tmp_path / "p.h5")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].lstrip().startswith("canopy height")
    assert "tallest stem within the footprint" in lines[1]
    assert lines[2].lstrip().startswith("RH98 of the fitted waveform")
    assert lines[3].lstrip().startswith("canopy cover") and "L2B" in lines[3]
    assert lines[4].lstrip().startswith("crown cover")
    assert "stand top_height" in lines[5] and "upper limit" in lines[5]


def test_simulate_refuses_to_overwrite_and_names_the_file(tmp_path, capsys):
    out = tmp_path / "jp.h5"
    out.write_bytes(b"precious")
    args = ["simulate", "--example", "jack-pine", "-o", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert str(out) in err and "--overwrite" in err
    assert out.read_bytes() == b"precious"
    missing = tmp_path / "no-such-folder" / "jp.h5"
    assert main(["simulate", "--example", "jack-pine", "-o", str(missing)]) == 2
    assert str(missing) in capsys.readouterr().err
    assert main([*args, "--overwrite"]) == 0
    with h5py.File(out) as handle:
        assert handle.attrs["content"] == "lidarinv simulated waveforms"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["jp.h5"]  # no temporary left


# -- values the parser refuses ---------------------------------------------------------


@pytest.mark.parametrize(
    "option",
    [
        ["--walkers", "1"],
        ["--walkers", "27"],
        ["--max-steps", "0"],
        ["--max-steps", "-5"],
        ["--instrument", "icesat"],
        ["--cohorts", "3"],
        ["--footprint-cover", "0"],
    ],
)
def test_parser_refuses_values_a_run_cannot_use(option, capsys):
    for command in ("invert", "batch"):
        with pytest.raises(SystemExit) as stop:
            build_parser().parse_args([command, "x.h5", "-o", "y.h5", *option])
        assert stop.value.code == 2
        assert option[0] in capsys.readouterr().err


def test_walkers_below_the_ensembles_minimum_are_refused_before_sampling(
    tmp_path, capsys, fake_inversion
):
    assert main([*INVERT_EXAMPLE, "-o", str(tmp_path / "p.h5"), "--walkers", "8"]) == 2
    err = capsys.readouterr().err
    # cohorts "auto" may sample the two-cohort model: three parameters more, and its
    # tallest-stem latent one more
    assert "at least 34 walkers for 16 sampled parameters" in err
    assert fake_inversion == [] and not (tmp_path / "p.h5").exists()
    assert main([*INVERT_EXAMPLE, "-o", str(tmp_path / "p.h5"), "--walkers", "34"]) == 0


def test_two_cohorts_need_more_walkers_and_auto_counts_them_too(tmp_path, capsys, fake_inversion):
    for cohorts in ("2", "auto"):
        args = [*INVERT_EXAMPLE, "-o", str(tmp_path / "p.h5"), "--walkers", "26"]
        assert main([*args, "--cohorts", cohorts]) == 2
        assert "for 16 sampled parameters" in capsys.readouterr().err
    args = build_parser().parse_args(["invert", "x.h5", "-o", "y.h5", "--cohorts", "auto"])
    assert inversion_settings(args).cohorts == "auto"


def test_batch_takes_max_steps_walkers_and_instrument():
    args = build_parser().parse_args(
        [
            "batch",
            "f.h5",
            "-o",
            "r.h5",
            "--max-steps",
            "300",
            "--walkers",
            "40",
            "--instrument",
            "lvis",
        ]
    )
    settings = batch_settings(args)
    assert (settings.sampler.max_steps, settings.sampler.n_walkers) == (300, 40)
    assert settings.instrument == "lvis"
    assert batch_settings(build_parser().parse_args(["batch", "f.h5", "-o", "r.h5"])) is None
    auto = build_parser().parse_args(["batch", "f.h5", "-o", "r.h5", "--cohorts", "auto"])
    assert batch_settings(auto).cohorts == "auto"
    drawn = build_parser().parse_args(["batch", "f.h5", "-o", "r.h5", "--footprint-cover", "64"])
    assert batch_settings(drawn).footprint_cover_draws == 64


# -- batch: failures in the exit status, shots not found ---------------------------------


def _batch_file(tmp_path, n=4, unreadable=()):
    path = tmp_path / "obs.h5"
    obs = list(fake_observations(n, np.random.default_rng(1)))
    for shot in unreadable:
        obs[shot].samples[5] = np.nan
    write_observations(path, obs)
    return path


FAKE = [
    "--workers",
    "1",
    "--no-progress",
    "--invert",
    "lidarinv.testing.fake_inversion:fake_invert",
]


def test_batch_exits_non_zero_when_a_shot_failed(tmp_path, capsys):
    path = _batch_file(tmp_path, unreadable={1})
    assert main(["batch", str(path), "-o", str(tmp_path / "r.h5"), *FAKE]) == 1
    out = capsys.readouterr().out
    assert "3 done, 1 failed" in out and "# failed 1: unreadable" in out


def test_batch_says_which_shots_it_did_not_find(tmp_path, capsys):
    path = _batch_file(tmp_path)
    args = ["batch", str(path), "-o", str(tmp_path / "r.h5"), *FAKE, "--shot", "2"]
    assert main([*args, "--shot", "99"]) == 1
    out = capsys.readouterr().out
    assert "1 done, 0 failed" in out
    assert f"shot(s) not found in {path}: 99" in out


def test_batch_overwrite_starts_afresh(tmp_path, capsys):
    path = _batch_file(tmp_path)
    out = tmp_path / "r.h5"
    assert main(["batch", str(path), "-o", str(out), *FAKE]) == 0
    assert main(["batch", str(path), "-o", str(out), *FAKE]) == 0
    assert "0 done, 0 failed, 4 skipped" in capsys.readouterr().out  # resumed, not replaced
    assert main(["batch", str(path), "-o", str(out), *FAKE, "--overwrite"]) == 0
    assert "4 done, 0 failed, 0 skipped" in capsys.readouterr().out


# -- Ctrl-C ------------------------------------------------------------------------------


def test_ctrl_c_during_invert_prints_one_line_and_leaves_no_file(tmp_path, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(lidarinv.inference, "invert_shot", interrupted)
    out = tmp_path / "post.h5"
    assert main([*INVERT_EXAMPLE, "-o", str(out)]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["lidarinv invert: interrupted; no partial output kept"]
    assert list(tmp_path.iterdir()) == []


def test_an_interrupted_save_leaves_the_file_as_it_was(tmp_path):
    out = tmp_path / "post.h5"

    def half_written(group):
        group.create_dataset("samples", data=np.zeros(10))
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        save_group(out, "shot_1", half_written)
    assert not out.exists()  # no file where there was none
    save_group(out, "shot_1", tiny_result(1).write)
    with pytest.raises(KeyboardInterrupt):
        save_group(out, "shot_1", half_written)
    with h5py.File(out) as handle:
        assert list(handle) == ["shot_1"] and "samples" in handle["shot_1"]
    assert InversionResult.load(out, "shot_1").samples.shape == (200, 3)


def test_ctrl_c_during_batch_leaves_no_file_when_nothing_finished(tmp_path, capsys, monkeypatch):
    import lidarinv.batch

    def interrupted(observations, settings=None, *, output, **kwargs):
        h5py.File(output, "a").close()  # the store creates the file first
        raise KeyboardInterrupt

    monkeypatch.setattr(lidarinv.batch, "invert_many", interrupted)
    path = _batch_file(tmp_path)
    out = tmp_path / "r.h5"
    assert main(["batch", str(path), "-o", str(out), *FAKE]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "interrupted" in err[0]
    assert not out.exists() and not out.with_suffix(".csv").exists()


def test_local_workers_leave_ctrl_c_to_the_coordinator():
    import signal
    from concurrent.futures import ProcessPoolExecutor

    from lidarinv.batch.executors import init_worker

    with ProcessPoolExecutor(1, initializer=init_worker, initargs=(None, None)) as pool:
        handler = pool.submit(signal.getsignal, signal.SIGINT).result()
    assert handler == signal.SIG_IGN
    assert os.environ.get("OMP_NUM_THREADS") != "changed"  # the coordinator's is untouched


# -- the progress bar ----------------------------------------------------------------------


def test_progress_bar_ends_full_and_says_converged_before_the_step_cap(capsys):
    from lidarinv.inference.model.priors import Uniform
    from lidarinv.inference.model.space import Parameter, ParameterSpace
    from lidarinv.inference.sampling import SamplerSettings, run_sampler

    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-10.0, 10.0)) for i in range(2))

    def gaussian(u):
        x, log_jac = space.from_unbounded(u)
        log_post = -0.5 * np.sum(x * x, axis=1) + space.log_prior(x) + log_jac
        return np.column_stack([log_post, x[:, 0]])

    settings = SamplerSettings(n_walkers=8, max_steps=20_000, check_every=100)
    run = run_sampler(gaussian, space, np.random.default_rng(2), settings, progress=True)
    assert run.converged and run.chain.shape[0] < settings.max_steps
    final = capsys.readouterr().err.replace("\r", "\n").strip().splitlines()[-1]
    assert "100%" in final and "converged" in final
    assert f"{run.chain.shape[0]}/{run.chain.shape[0]}" in final


def test_a_real_sigint_inside_a_kernel_still_ends_in_one_line(tmp_path, capsys, monkeypatch):
    """Ctrl-C lands where it lands: here inside a 'kernel' that, like numba, turns the
    KeyboardInterrupt into a SystemError, under a caller that, like emcee, prints the
    parameters and a traceback on its way out."""
    import signal
    import sys
    import traceback

    def kernel_then_noise(*args, **kwargs):
        try:
            try:
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(1000):  # the signal arrives here
                    sum(range(1000))
            except KeyboardInterrupt as error:
                raise SystemError("returned a result with an exception set") from error
        except SystemError:
            print("emcee: Exception while calling your likelihood function:")
            print("  params:", np.zeros((4, 12)))
            traceback.print_exc(file=sys.stderr)
            raise

    monkeypatch.setattr(lidarinv.inference, "invert_shot", kernel_then_noise)
    # as in a terminal (a process started in the background inherits SIGINT ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    out = tmp_path / "post.h5"
    try:
        code = main([*INVERT_EXAMPLE, "-o", str(out)])
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored
    finally:
        signal.signal(signal.SIGINT, previous)
    assert code == 130
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.strip().splitlines() == [
        "lidarinv invert: interrupted; no partial output kept"
    ]
    assert not out.exists()


def test_a_new_figure_folder_is_made_and_an_old_one_checked(tmp_path):
    from lidarinv.cli.outputs import check_plot_folder

    fresh = check_plot_folder(tmp_path / "plots", ["a.png"])  # the README's --plots plots
    assert fresh.is_dir()
    (fresh / "a.png").write_text("earlier figure")
    with pytest.raises(ValueError, match=r"a\.png exists; pass --overwrite"):
        check_plot_folder(fresh, ["a.png"])
    assert check_plot_folder(fresh, ["a.png"], overwrite=True) == fresh
