"""``lidarinv metrics`` on mission-layout and lidarinv files."""

import json

import numpy as np
from gedi_files import gedi_shot, write_gedi

from lidarinv.cli import main
from lidarinv.io import write_observations
from lidarinv.observe import Observation


def _gedi_file(tmp_path):
    rng = np.random.default_rng(3)
    good = gedi_shot(11, 250.0)
    empty = {
        "rx": 230.0 + 2.5 * rng.standard_normal(700),
        "top": 300.0,
        "bottom": 200.15,
        "shot": 12,
    }
    nan = gedi_shot(13, 250.0)
    nan["rx"][100] = np.nan
    truncated = gedi_shot(14, 251.0)
    truncated["count"] = 9999
    path = tmp_path / "gedi.h5"
    write_gedi(
        path, {"BEAM0000": [good, empty, nan, truncated], "BEAM0011": [gedi_shot(21, 260.0)]}
    )
    return path


def test_metrics_reports_every_shot_and_continues(tmp_path, capsys):
    path = _gedi_file(tmp_path)
    out_json = tmp_path / "metrics.json"
    code = main(["metrics", str(path), "--json", str(out_json), "--plot", str(tmp_path / "plots")])
    text = capsys.readouterr().out
    assert code == 0
    lines = {line.split()[0]: line for line in text.splitlines() if line.strip()}
    assert "ok" in lines["11"] and "no signal" in lines["12"]
    assert "skipped" in lines["13"] and "NaN" in lines["13"]
    assert "skipped" in lines["14"] and "truncated" in lines["14"]
    assert "ok" in lines["21"]
    records = {r["shot_id"]: r for r in json.loads(out_json.read_text())}
    assert abs(records[11]["ground"] - 250.0) < 0.05
    assert records[11]["rh100"] > records[11]["rh98"] > records[11]["rh50"]
    assert len([k for k in records[11] if k.startswith("rh")]) == 101
    assert records[12]["status"] == "no signal" and records[12]["ground"] is None
    assert records[13]["status"] == "error"
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == [
        "shot_11.png", "shot_12.png", "shot_21.png"]  # fmt: skip


def test_metrics_beam_selection_and_format(tmp_path, capsys):
    path = _gedi_file(tmp_path)
    assert main(["metrics", str(path), "--beam", "BEAM0011", "--format", "gedi-l1b"]) == 0
    text = capsys.readouterr().out
    assert "21" in text and "\n" + " " * 18 + "11 " not in text
    assert main(["metrics", str(path), "--format", "lvis-l1b"]) == 2
    assert "lvis-l1b layout" in capsys.readouterr().err


def test_metrics_on_a_lidarinv_file_and_missing_file(tmp_path, capsys):
    axis = 0.15 * np.arange(300)
    rng = np.random.default_rng(1)
    samples = 10.0 + 80.0 * np.exp(-0.5 * ((axis - 9.0) / 0.9) ** 2) + rng.standard_normal(300)
    path = tmp_path / "own.h5"
    write_observations(path, [Observation(samples, axis, shot_id=5)])
    assert main(["metrics", str(path)]) == 1  # the file names no instrument
    assert "which instrument" in capsys.readouterr().out
    assert main(["metrics", str(path), "--instrument", "gedi"]) == 0
    assert "ok" in capsys.readouterr().out
    named = tmp_path / "named.h5"
    write_observations(named, [Observation(samples, axis, shot_id=5, instrument="slicer")])
    assert main(["metrics", str(named)]) == 0
    assert "ok" in capsys.readouterr().out
    assert main(["metrics", str(tmp_path / "missing.h5")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_metrics_csv_and_json_of_real_shots(tmp_path, capsys):
    """The shipped GEDI example: a CSV a GIS can load (lat/lon, ground, RH, cover, PAVD,
    flags) and JSON with the same records; shot numbers stay integers."""
    import csv

    from lidarinv.io import example_file

    out_csv, out_json = tmp_path / "m.csv", tmp_path / "m.json"
    args = [
        "metrics",
        str(example_file("gedi-l1b")),
        "--csv",
        str(out_csv),
        "--json",
        str(out_json),
    ]
    assert main(args) == 0
    rows = list(csv.DictReader(out_csv.open()))
    records = json.loads(out_json.read_text())
    assert len(rows) == len(records) > 10
    assert all(isinstance(r["shot_id"], int) and r["shot_id"] > 10**15 for r in records)
    for key in ("latitude", "longitude", "ground", "rh98", "cover", "pavd_0_5", "quality"):
        assert key in rows[0]
    assert all(-90 <= float(r["latitude"]) <= 90 for r in rows if r["status"] == "ok")
    assert (
        main(["metrics", str(example_file("gedi-l1b")), "--csv", str(tmp_path / "no" / "m.csv")])
        == 2
    )
    assert "does not exist" in capsys.readouterr().err
