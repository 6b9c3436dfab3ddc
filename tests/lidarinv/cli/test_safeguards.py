"""What a new user meets (issue 47): no file replaced without --overwrite, the file's own
instrument wins, absurd samples refused before sampling, I/O errors that name the file
with nothing on stdout first, a word before the kernels compile, progress totals of the
shots processed, and the beam as a plain early column."""

import csv
import json
import shutil
import sys
import textwrap

import h5py
import numpy as np
import pytest
from gedi_files import gedi_shot, write_gedi
from tiny_results import tiny_result

import lidarinv.inference
from lidarinv.batch.progress import ProgressBar
from lidarinv.cli import main
from lidarinv.cli.kernels import NOTICE, announce_compilation, cold_kernels
from lidarinv.inference import InversionResult
from lidarinv.io import example_file, write_observations
from lidarinv.io.formats import inspect_file
from lidarinv.testing.fake_inversion import fake_observations

FAKE_BATCH = [
    "--workers",
    "1",
    "--no-progress",
    "--invert",
    "lidarinv.testing.fake_inversion:fake_invert",
]


@pytest.fixture
def sampler(monkeypatch):
    """An instant stand-in for the sampler that records the shots it was called for."""
    calls = []

    def invert(observation, settings=None, *, rng=None, progress=False, **_):
        calls.append(observation.shot_id)
        return tiny_result(observation.shot_id)

    monkeypatch.setattr(lidarinv.inference, "invert_shot", invert)
    monkeypatch.setattr("lidarinv.cli.kernels.cold_kernels", lambda: [])
    return calls


@pytest.fixture
def lvis_file(tmp_path):
    path = tmp_path / "lvis.h5"
    shutil.copy(example_file("lvis-l1b"), path)
    return path


def _gedi_file(tmp_path, bad=None):
    """Two beams of clean shots; ``bad`` replaces samples of shot 12 by ``bad``."""
    shots = [gedi_shot(11, 250.0), gedi_shot(12, 251.0)]
    if bad is not None:
        shots[1]["rx"][300:304] = bad
    path = tmp_path / "gedi.h5"
    write_gedi(path, {"BEAM0000": shots, "BEAM0101": [gedi_shot(21, 260.0)]})
    return path


def _one_line_error(captured, path):
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and "Traceback" not in captured.err
    return lines[0]


# -- 1. nothing replaced without --overwrite ------------------------------------------------


def test_metrics_refuses_existing_csv_and_json_before_any_work(tmp_path, capsys):
    table, record = tmp_path / "m.csv", tmp_path / "m.json"
    table.write_text("precious")
    record.write_text("precious too")
    args = ["metrics", str(_gedi_file(tmp_path)), "--csv", str(table), "--json", str(record)]
    assert main(args) == 2
    line = _one_line_error(capsys.readouterr(), table)
    assert str(record) in line and "--overwrite" in line
    assert table.read_text() == "precious" and record.read_text() == "precious too"
    assert main([*args, "--overwrite"]) == 0
    assert table.read_text().startswith("shot_id,") and json.loads(record.read_text())


def test_metrics_refuses_figures_of_an_earlier_run(tmp_path, capsys):
    figures = tmp_path / "figures"
    figures.mkdir()
    earlier = figures / "shot_11.png"
    earlier.write_bytes(b"earlier figure")
    args = ["metrics", str(_gedi_file(tmp_path)), "--plot", str(figures)]
    assert main(args) == 2
    _one_line_error(capsys.readouterr(), earlier)
    assert earlier.read_bytes() == b"earlier figure"


def test_invert_refuses_figures_it_would_replace_before_sampling(tmp_path, capsys, sampler):
    figures = tmp_path / "figures"
    figures.mkdir()
    earlier = figures / "shot_gedi-mixed_corner.png"
    earlier.write_bytes(b"earlier figure")
    args = ["invert", "--example", "gedi-mixed", "--quiet", "-o", str(tmp_path / "p.h5")]
    assert main([*args, "--plots", str(figures)]) == 2
    assert str(earlier) in capsys.readouterr().err
    assert sampler == [] and earlier.read_bytes() == b"earlier figure"


def test_invert_checks_the_first_shots_figures_before_sampling_it(tmp_path, capsys, sampler):
    path = _gedi_file(tmp_path)
    figures = tmp_path / "figures"
    figures.mkdir()
    (figures / "shot_11_profile.png").write_bytes(b"earlier figure")
    args = ["invert", str(path), "--quiet", "-o", str(tmp_path / "p.h5"), "--plots", str(figures)]
    assert main(args) == 2
    assert "shot_11_profile.png" in capsys.readouterr().err and sampler == []


def test_batch_never_replaces_an_unrelated_csv_beside_its_results(tmp_path, capsys):
    path = tmp_path / "obs.h5"
    write_observations(path, list(fake_observations(3, np.random.default_rng(1))))
    results, beside = tmp_path / "res.h5", tmp_path / "res.csv"
    beside.write_text("a user's own table\n")
    args = ["batch", str(path), "-o", str(results), *FAKE_BATCH]
    assert main(args) == 2
    _one_line_error(capsys.readouterr(), beside)
    assert beside.read_text() == "a user's own table\n" and not results.exists()
    assert main([*args, "--overwrite"]) == 0
    assert beside.read_text().startswith("shot_id,")
    assert main(args) == 0  # a resumed run rewrites its own summary
    assert "0 done, 0 failed, 3 skipped" in capsys.readouterr().out


def test_batch_refuses_a_results_file_that_is_not_one(tmp_path, capsys):
    path = tmp_path / "obs.h5"
    write_observations(path, list(fake_observations(2, np.random.default_rng(1))))
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as handle:
        handle["precious"] = np.arange(3)
    assert main(["batch", str(path), "-o", str(other), *FAKE_BATCH]) == 2
    _one_line_error(capsys.readouterr(), other)
    with h5py.File(other) as handle:
        assert list(handle) == ["precious"]
    assert main(["batch", str(path), "-o", str(path), *FAKE_BATCH, "--overwrite"]) == 2
    assert "is the input file" in capsys.readouterr().err and path.exists()


# -- 2. the file's own instrument wins ----------------------------------------------------------


def test_the_instrument_comes_from_the_layout():
    assert inspect_file(example_file("lvis-l1b")).instrument == "lvis"
    assert inspect_file(example_file("gedi-l1b")).instrument == "gedi"


def test_metrics_refuses_an_instrument_the_file_contradicts(lvis_file, tmp_path, capsys):
    record = tmp_path / "m.json"
    args = ["metrics", str(lvis_file), "--instrument", "gedi", "--shots", "2"]
    assert main([*args, "--json", str(record)]) == 2
    line = _one_line_error(capsys.readouterr(), lvis_file)
    assert "--instrument gedi" in line and "lvis" in line and not record.exists()
    assert main([*args, "--json", str(record), "--override-instrument"]) == 0
    assert "warning: instrument gedi overrides the file's lvis" in capsys.readouterr().err
    records = json.loads(record.read_text())
    assert all("instrument gedi overrides the file's lvis" in " ".join(r["flags"]) for r in records)
    assert main(["metrics", str(lvis_file), "--instrument", "lvis", "--shots", "1"]) == 0


def test_invert_refuses_a_contradicting_instrument_before_sampling(
    lvis_file, tmp_path, capsys, sampler
):
    out = tmp_path / "p.h5"
    args = ["invert", str(lvis_file), "--quiet", "-o", str(out), "--instrument", "gedi"]
    assert main(args) == 2
    line = _one_line_error(capsys.readouterr(), lvis_file)
    assert "gedi" in line and "lvis" in line
    assert sampler == [] and not out.exists()
    assert main([*args, "--override-instrument"]) == 0
    [group] = h5py.File(out, "r").keys()
    assert any(
        "overrides the file's lvis" in flag for flag in InversionResult.load(out, group).flags
    )


def test_batch_refuses_a_contradicting_instrument(lvis_file, tmp_path, capsys):
    out = tmp_path / "r.h5"
    args = ["batch", str(lvis_file), "-o", str(out), *FAKE_BATCH, "--instrument", "gedi"]
    assert main(args) == 2
    line = _one_line_error(capsys.readouterr(), lvis_file)
    assert "gedi" in line and "lvis" in line and not out.exists()


# -- 3. absurd samples found before sampling ---------------------------------------------------


def test_absurd_samples_are_refused_before_sampling(tmp_path, capsys, sampler):
    path = _gedi_file(tmp_path, bad=1e30)
    assert main(["metrics", str(path)]) == 0
    rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()}
    assert "skipped" in rows["12"] and "absurd" in rows["12"] and "ok" in rows["11"]
    out = tmp_path / "p.h5"
    assert main(["invert", str(path), "--shot", "12", "--quiet", "-o", str(out)]) == 1
    assert "shot 12: skipped: 4 absurd sample(s) (up to 1e+30" in capsys.readouterr().out
    assert sampler == []  # the sampler never saw it
    assert main(["batch", str(path), "-o", str(tmp_path / "r.h5"), *FAKE_BATCH]) == 1
    assert "# failed 12 (BEAM0000): unreadable: 4 absurd sample(s)" in capsys.readouterr().out


def test_a_clipped_return_is_named_before_sampling(tmp_path, capsys, sampler):
    shot = gedi_shot(12, 251.0)
    shot["rx"][597:604] = shot["rx"].max()  # a plateau at the maximum: clipped
    path = tmp_path / "clipped.h5"
    write_gedi(path, {"BEAM0000": [shot]})
    assert main(["invert", str(path), "--quiet", "-o", str(tmp_path / "p.h5")]) == 0
    assert "shot 12: clipped return" in capsys.readouterr().err and sampler == [12]


# -- 4. I/O errors name the file, nothing on stdout first ----------------------------------------


@pytest.fixture
def unreadable_files(tmp_path):
    empty = tmp_path / "empty.h5"
    empty.write_bytes(b"")
    text = tmp_path / "text.h5"
    text.write_text("latitude,longitude\n1,2\n")
    truncated = tmp_path / "truncated.h5"
    whole = example_file("lvis-l1b").read_bytes()
    truncated.write_bytes(whole[: len(whole) // 2])
    return {"empty": empty, "text": text, "truncated": truncated}


@pytest.mark.parametrize("command", ["metrics", "invert", "batch"])
def test_unreadable_files_give_one_line_naming_them(unreadable_files, tmp_path, capsys, command):
    expected = {"empty": "empty file", "text": "not an HDF5 file", "truncated": "truncated"}
    for kind, path in unreadable_files.items():
        args = [command, str(path)]
        if command != "metrics":
            args += ["-o", str(tmp_path / f"{command}-out.h5")]
        assert main(args) == 2
        line = _one_line_error(capsys.readouterr(), path)
        assert expected[kind] in line and "file signature not found" not in line
    assert not (tmp_path / f"{command}-out.h5").exists()


# -- 5. a word before the kernels compile ----------------------------------------------------------


def test_a_cold_kernel_is_found_and_warm_once_compiled(tmp_path, monkeypatch):
    numba = pytest.importorskip("numba")
    from forward import backends

    source = tmp_path / "tiny_kernel_for_cache_test.py"
    source.write_text(
        textwrap.dedent(
            """
            def twice(x):
                return 2.0 * x
            """
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    module = __import__("tiny_kernel_for_cache_test")
    kernel = numba.njit(cache=True)(module.twice)
    monkeypatch.setattr(backends, "_DISPATCHERS", {("twice", ()): kernel})
    assert cold_kernels() == ["twice"]
    assert kernel(2.0) == 4.0
    assert cold_kernels() == []  # compiled here, and now in the cache on disk
    sys.modules.pop("tiny_kernel_for_cache_test", None)


def test_the_notice_needs_most_kernels_cold(monkeypatch, capsys):
    from forward import backends

    monkeypatch.setattr(backends, "_DISPATCHERS", dict.fromkeys("abcd"))
    monkeypatch.setattr("lidarinv.cli.kernels.cold_kernels", lambda: ["a"])
    assert not announce_compilation()  # one kernel a first run did not call
    monkeypatch.setattr("lidarinv.cli.kernels.cold_kernels", lambda: ["a", "b", "c"])
    assert announce_compilation("lidarinv invert")
    assert capsys.readouterr().err == f"lidarinv invert: {NOTICE}\n"


def test_invert_says_it_compiles_before_the_first_sampling(tmp_path, capsys, monkeypatch):
    from forward import backends

    said = []

    def invert(observation, settings=None, **_):
        said.append(capsys.readouterr().err)  # what was printed before the sampler ran
        return tiny_result(observation.shot_id)

    monkeypatch.setattr(lidarinv.inference, "invert_shot", invert)
    monkeypatch.setattr("lidarinv.cli.kernels.cold_kernels", lambda: list(backends._DISPATCHERS))
    args = ["invert", "--example", "gedi-mixed", "--quiet", "-o", str(tmp_path / "p.h5")]
    assert main(args) == 0
    assert said == [f"lidarinv invert: {NOTICE}\n"]


# -- 6. progress totals count the shots processed ---------------------------------------------------


def test_batch_progress_total_is_max_shots(tmp_path, capsys):
    path = tmp_path / "obs.h5"
    write_observations(path, list(fake_observations(12, np.random.default_rng(1))))
    args = ["batch", str(path), "-o", str(tmp_path / "r.h5"), "--max-shots", "3"]
    fake = ["--workers", "1", "--invert", "lidarinv.testing.fake_inversion:fake_invert"]
    assert main([*args, *fake]) == 0
    bars = capsys.readouterr().err.replace("\r", "\n")
    assert "3/3" in bars and "/12" not in bars


def test_progress_total_leaves_out_stored_shots_and_counts_unreadable_ones():
    bar = ProgressBar(total=10, enabled=False)
    for _ in range(4):
        bar.skipped()  # a resumed file holds them
    assert bar.expected == 6
    capped = ProgressBar(total=186, enabled=False, cap=6)
    assert capped.expected == 6
    capped.unreadable()  # failed at once, and not counted against max_shots
    capped.started()
    assert capped.expected == 7


# -- 7. the beam, a plain early column ------------------------------------------------------------


def test_metrics_tables_carry_the_beam_second(tmp_path, capsys):
    path = _gedi_file(tmp_path)
    table, record = tmp_path / "m.csv", tmp_path / "m.json"
    assert main(["metrics", str(path), "--csv", str(table), "--json", str(record)]) == 0
    header, *rows = capsys.readouterr().out.splitlines()
    assert header.split()[:2] == ["shot", "beam"]
    assert {row.split()[0]: row.split()[1] for row in rows[:3]} == {
        "11": "BEAM0000", "12": "BEAM0000", "21": "BEAM0101"}  # fmt: skip
    with open(table, newline="") as handle:
        columns = next(csv.reader(handle))
    assert columns[:2] == ["shot_id", "beam"] and "meta_beam" not in columns
    assert list(json.loads(record.read_text())[0])[:2] == ["shot_id", "beam"]


def test_metrics_of_a_format_without_beams_has_no_beam_column(lvis_file, capsys):
    assert main(["metrics", str(lvis_file), "--shots", "1"]) == 0
    assert "beam" not in capsys.readouterr().out.splitlines()[0]


def test_batch_summary_carries_the_beam_second(tmp_path, capsys):
    path = _gedi_file(tmp_path)
    assert main(["batch", str(path), "-o", str(tmp_path / "r.h5"), *FAKE_BATCH]) == 0
    with open(tmp_path / "r.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0])[:2] == ["shot_id", "beam"]
    assert [row["beam"] for row in rows] == ["BEAM0000", "BEAM0000", "BEAM0101"]
