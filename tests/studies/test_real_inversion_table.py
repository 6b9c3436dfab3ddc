"""The real-data inversion's per-shot rows (``studies/real_inversion_table.py``) and the
validation page's per-shot figure and table drawn from them."""

import json

import numpy as np


def _record(shot, rh98, flags, converged=True):
    return {
        "shot": shot,
        "instrument": "lvis",
        "lfid": "1",
        "cohorts": 2,
        "converged": converged,
        "cpu_seconds": 301.27,
        "flags": flags,
        "product": {"ground": 30.0, "rh98": 44.0, "cover": np.nan, "rh98_model_convention": 44.0},
        "posterior": {
            "ground": [29.9, 30.1, 30.3],
            "rh98": [rh98 - 2.0, rh98, rh98 + 2.0],
            "rh98_footprint": [43.0, 44.2, 45.0],
            "rh98_product": [np.nan, np.nan, np.nan],
            "cover": [0.8, 0.9, 0.95],
        },
    }


def test_a_row_keeps_the_flags_kinds_and_drops_what_is_not_finite():
    from real_inversion_table import flag_label, shot_rows

    flags = [
        "canopy height below the waveform's RH98: in 80% of draws the tallest stem ...",
        "not converged at the step cap (20000 steps): cover R̂ 1.020 > 1.01",
        "model error raised: the residuals at the MAP exceed the noise",
    ]
    (row,) = shot_rows([_record(10969487, 34.2, flags, converged=False)])
    assert row["shot"] == "10969487" and row["converged"] is False
    assert row["flags"] == sorted(flag_label(f) for f in flags)
    assert "not converged at the step cap" in row["flags"] and row["warned"]
    assert row["posterior"]["rh98"] == [32.2, 34.2, 36.2]
    assert row["posterior"]["rh98_product"] == [None, None, None]
    assert "cover" not in row["posterior"] and "canopy_height" not in row["posterior"]
    json.dumps(row, allow_nan=False)  # publishable as it is


def test_the_page_draws_the_shots_and_lists_them_with_their_warnings(tmp_path):
    from real_inversion_table import shot_rows
    from validation.render_inversion import TABLE_ROWS, per_shot_section

    clean = _record(1, 44.5, ["model error raised: ..."])
    short = _record(2, 20.0, ["canopy height below the waveform's RH98: ..."])
    rows = shot_rows([clean, short])
    assert not rows[0]["warned"] and rows[1]["warned"]  # "model error raised" is no warning
    text = per_shot_section(rows, tmp_path, "real-inversion-tall", "lvis")
    figure = tmp_path / "real-inversion-tall-lvis-rh98.png"
    assert figure.stat().st_size > 5000 and figure.name in text
    assert "list-table" in text and "42.5/44.5/46.5" in text and "18.0/20.0/22.0" in text
    many = shot_rows([clean] * (TABLE_ROWS + 1))
    assert "list-table" not in per_shot_section(many, tmp_path, "k", "lvis")  # figure only
    assert per_shot_section([], tmp_path, "k", "lvis") == ""


def test_far_off_answers_count_apart_when_they_carry_no_warning():
    import real_inversion

    quiet = _record(1, 20.0, ["model error raised: ..."])  # 24 m below the product
    flagged = _record(2, 20.0, ["misfit: between 11.8 and 34.0 m ..."])
    close = _record(3, 44.0, [])
    stats = real_inversion.statistics([quiet, flagged, close], "lvis")
    far = stats["rh98_model_convention"]
    assert far["far_off"] == 2 and far["far_off_unwarned"] == 1
    assert stats["ground"]["far_off"] == 0
    assert [row["shot"] for row in stats["per_shot"]] == ["1", "2", "3"]
