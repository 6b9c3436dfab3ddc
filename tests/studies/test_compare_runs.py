"""Two real-data runs compared shot by shot (``studies/compare_runs.py``)."""

import json

import numpy as np
import pytest


def _record(shot, median, *, steps=800, flags=(), instrument="gedi"):
    """A shot whose posterior RH98 has an sd of 1 m (its 5–95 % interval 3.29 m wide)."""
    half = 3.29 / 2
    return {
        "shot": shot,
        "instrument": instrument,
        "cpu_seconds": steps / 100,
        "steps": steps,
        "converged": True,
        "flags": list(flags),
        "product": {"ground": 100.0, "rh98": 10.0, "cover": 0.3, "rh98_model_convention": 10.0},
        "posterior": {
            "rh98": [median - half, median, median + half],
            "ground": [99.9, 100.1, 100.3],
            "cover": [0.2, 0.3, 0.4],
        },
    }


def _run(folder, tag, records):
    run = folder / f"real_inversion{tag}"
    run.mkdir()
    (run / "shots.json").write_text(json.dumps(records))


@pytest.fixture
def output(tmp_path, monkeypatch):
    import harness

    monkeypatch.setattr(harness, "OUTPUT", tmp_path)
    return tmp_path


def test_a_run_against_itself_moves_nothing(output):
    import compare_runs

    records = [_record(k, 10.0 + k) for k in range(5)]
    _run(output, "_a", records)
    runs = compare_runs.read_records("_a")
    gedi = compare_runs.compare(runs, runs)["gedi"]
    assert gedi["shots"] == 5
    assert gedi["quantile_shift_sd"]["rh98"]["largest"] == [0.0, 0.0, 0.0]
    assert json.dumps(gedi["first"]) == json.dumps(gedi["second"])  # NaN where no quantity


def test_shifts_are_in_the_first_runs_sd_over_the_shots_both_hold(output):
    import compare_runs

    first = [_record(1, 10.0), _record(2, 10.0), _record(3, 10.0, instrument="lvis")]
    # shot 1 moves by half an sd, shot 2 by two; shot 4 is in the second run alone
    second = [_record(1, 10.5, steps=1200), _record(2, 12.0, flags=["misfit: ..."]),
              _record(4, 30.0)]  # fmt: skip
    _run(output, "_a", first)
    _run(output, "_b", second)
    summary = compare_runs.compare(compare_runs.read_records("_a"), compare_runs.read_records("_b"))
    assert set(summary) == {"gedi"}  # the LVIS shot is in the first run alone
    gedi = summary["gedi"]
    assert gedi["shots"] == 2
    np.testing.assert_allclose(gedi["quantile_shift_sd"]["rh98"]["largest"], [2.0, 2.0, 2.0])
    np.testing.assert_allclose(gedi["quantile_shift_sd"]["rh98"]["median"], [1.25, 1.25, 1.25])
    assert gedi["first"]["warned"] == 0 and gedi["second"]["warned"] == 1
    assert gedi["second"]["steps_median"] == 1000.0
    assert gedi["first"]["product_error_median"]["rh98"] == 0.0
    assert gedi["second"]["product_error_median"]["rh98"] == 1.25


def test_a_missing_run_is_named(output):
    import compare_runs

    with pytest.raises(FileNotFoundError, match="_nowhere"):
        compare_runs.read_records("_nowhere")
