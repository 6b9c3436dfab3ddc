"""The documentation builds with warnings as errors, running every tutorial; the
validation pages say so where a study's summary is absent."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


@pytest.mark.docs
def test_docs_build_without_warnings_and_run_the_tutorials(tmp_path):
    pytest.importorskip("sphinx")
    pytest.importorskip("sphinx_gallery")
    pytest.importorskip("numpydoc")
    out = tmp_path / "html"
    command = [
        sys.executable,
        "-m",
        "sphinx",
        "-W",
        "--keep-going",
        "-q",
        "-b",
        "html",
        "-d",
        str(tmp_path / "doctrees"),
        str(DOCS),
        str(out),
    ]
    env = {**os.environ, "LIDARINV_DOCS_RERUN": "1", "MPLBACKEND": "Agg"}
    run = subprocess.run(command, capture_output=True, text=True, env=env, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-5000:]
    for page in (
        "index",
        "getting-started",
        "auto_tutorials/plot_02_invert_shot",
        "how-to/log-posterior",
        "explanation/conventions",
        "validation/generated/calibration",
        "api/_packages/lidarinv.inference",
    ):
        assert (out / f"{page}.html").exists(), page
    tutorial = (out / "auto_tutorials" / "plot_02_invert_shot.html").read_text()
    assert "canopy height" in tutorial and "sphx-glr-script-out" in tutorial  # it ran
    for real in ("plot_05_real_metrics", "plot_06_invert_real_shot"):  # real shots, run
        page = (out / "auto_tutorials" / f"{real}.html").read_text()
        assert "sphx-glr-script-out" in page and "L2A" in page


def test_validation_pages_say_when_a_summary_is_absent(tmp_path):
    from validation.generate import write_validation_pages

    (tmp_path / "data").mkdir()
    pages = {p.stem: p.read_text() for p in write_validation_pages(tmp_path)}
    assert set(pages) == {"accuracy", "speed", "calibration", "real-products"}
    assert "No summary published for ``calibration`` yet" in pages["calibration"]
    assert "python studies/recovery.py" in pages["calibration"]


def test_validation_pages_turn_a_summary_into_a_table_and_figure(tmp_path):
    from validation.generate import write_validation_pages

    (tmp_path / "data").mkdir()
    summary = {
        "n_shots": 10,
        "n_inverted": 9,
        "converged_fraction": 1.0,
        "truth": "prior",
        "median_seconds_per_shot": 8.5,
        "explicit_realisations": True,
        "binomial_95_range": {"68": [0.44, 0.89], "90": [0.67, 1.0]},
        "quantities": {
            "cover": {
                "n": 9,
                "coverage_68": 0.667,
                "coverage_90": 0.889,
                "z_median": 0.1,
                "z_spread": 1.0,
                "bias": -0.01,
                "rmse": 0.2,
                "direct_rmse": 0.3,
            }
        },
    }
    record = {
        "key": "calibration",
        "source": "studies/output/recovery_x/summary.json",
        "command": "python studies/recovery.py --n 10",
        "published": "2025-01-01",
        "commit": "abc123",
        "summary": summary,
    }
    (tmp_path / "data" / "calibration.json").write_text(json.dumps(record))
    write_validation_pages(tmp_path)
    page = (tmp_path / "generated" / "calibration.rst").read_text()
    assert "0.667" in page and "0.889" in page and "python studies/recovery.py --n 10" in page
    assert (tmp_path / "generated" / "calibration.png").stat().st_size > 5000


def test_validation_pages_show_out_of_family_coverage_per_stand_kind(tmp_path):
    from validation.generate import write_validation_pages

    (tmp_path / "data").mkdir()
    quantities = {"cover": {"n": 3, "coverage_68": 0.333, "coverage_90": 0.667}}
    part = {"n_shots": 3, "n_inverted": 3, "converged_fraction": 1.0,
            "binomial_95_range": {"90": [0.333, 1.0]}}  # fmt: skip
    summary = {
        **part,
        "n_shots": 6,
        "n_inverted": 5,
        "truth": "out-of-family",
        "quantities": quantities,
        "by_kind": {
            "emergent": {**part, "quantities": {"cover": {"coverage_90": 0.123}}},
            "sparse": {**part, "n_inverted": 2, "quantities": {"cover": {"coverage_90": 0.5}}},
        },
    }
    record = {"key": "calibration-out-of-family", "source": "s", "command": "c",
              "published": "2025-01-01", "commit": "abc", "summary": summary}  # fmt: skip
    (tmp_path / "data" / "calibration-out-of-family.json").write_text(json.dumps(record))
    page = {p.stem: p for p in write_validation_pages(tmp_path)}["calibration"].read_text()
    assert "Explicit stands from outside the model family" in page
    assert "emergent" in page and "0.123" in page and "2 of 3" in page


def test_every_validation_section_shows_a_published_summary_in_words(tmp_path):
    """The committed summaries fill every section, and the tables show labels, not the
    summaries' JSON keys (``load_average_1min``, ``pareto_front``)."""
    import re
    import shutil

    from validation.generate import PAGES, write_validation_pages

    shutil.copytree(DOCS / "validation" / "data", tmp_path / "data")
    pages = {p.stem: p.read_text() for p in write_validation_pages(tmp_path)}
    assert set(pages) == set(PAGES)
    for name, text in pages.items():
        assert "No summary published" not in text, name
        # titles, header rows and field names are words; quantity names stay ``literals``
        for block in text.split(".. list-table::")[1:]:
            rows = re.findall(r"^   \* - (.*)\n((?:     - .*\n)*)", block, re.M)
            labels = [block.split("\n")[0], rows[0][0], *rows[0][1].split("\n")]
            labels += [first for first, _ in rows[1:]]
            for words in (re.sub(r"``[^`]*``", "", cell) for cell in labels):
                assert not re.search(r"[a-z]_[a-z]", words), (name, words)
    accuracy = pages["accuracy"]
    assert "load_average" not in accuracy and "pareto_front" not in accuracy
    assert "load average over 1 min" in accuracy and "Pareto front" in accuracy


def test_no_user_page_names_a_development_path():
    sources = [*DOCS.rglob("*.rst"), *DOCS.rglob("*.py"), ROOT / "README.md"]
    for path in sources:
        if "_build" in path.parts or "generated" in path.parts:
            continue
        assert "shared/data" not in path.read_text(), path
