"""Which of a result's flags warn that its answer may be wrong (``results.flags``): the
flags the passes and the sampler write are classified by the words they begin with."""

import numpy as np
from tiny_results import tiny_result

from lidarinv.cli.invert import headline
from lidarinv.inference.likelihood.gaussian import WHITE_NOISE_NOTE
from lidarinv.inference.passes.ambiguity import describe, describe_modes
from lidarinv.inference.passes.cohorts import CohortChoice
from lidarinv.inference.passes.model_error import describe_floor, describe_misfit
from lidarinv.inference.results.flags import FLAG_KINDS, flag_kind, is_warning
from lidarinv.inference.results.footprint import canopy_height_note, stand_rh98_note
from lidarinv.inference.sampling.sampler import SamplerSettings, _not_converged
from lidarinv.inference.sampling.start import Mode


def _written_flags():
    """Flags as the code writes them, each with whether it should warn."""
    modes = {"grounds": [30.3, 26.1], "prior_weights": [0.7, 0.3],
             "posterior_probability": [0.55, 0.45]}  # fmt: skip
    ridge = [
        (Mode(np.zeros(2), -10.0, np.eye(2)), 30.3),
        (Mode(np.ones(2), -11.0, np.eye(2)), 26.1),
    ]
    undecided = CohortChoice(1, {1: -500.0, 2: -498.0}, {1: 1010.0, 2: 1012.0}, True, 20.0, 2.2)
    stopped = _not_converged(
        20000, SamplerSettings(), np.array([900.0]), ["rh98 R̂ 1.02 > 1.01"], {}
    )
    short = canopy_height_note(np.full(50, 20.0), np.full(50, 40.0), 2.2)
    low_stand = stand_rh98_note(np.full(50, 25.0), np.full(50, 33.0), 2.2)
    return [
        (describe_misfit(0.8), True),
        (short, True),
        (low_stand, True),
        (describe_modes(modes), True),
        (stopped, True),
        (describe(ridge), False),  # the walkers start at each ground: the posterior decides
        (describe_floor(0.3, 0.1), False),
        (undecided.note(), False),
        ("low acceptance in 3 walker(s)", False),
        (f"{WHITE_NOISE_NOTE}: the window holds censored or saturated samples", False),
        ("an instrument the caller chose", False),  # no known kind
    ]


def test_the_written_flags_are_warnings_or_notes_by_their_kind():
    for flag, warns in _written_flags():
        assert flag is not None
        assert is_warning(flag) is warns, flag
        kind = flag_kind(flag)
        assert (kind is None) == (flag == "an instrument the caller chose")
        assert kind is None or FLAG_KINDS[kind].meaning


def test_a_result_keeps_its_warnings_apart_and_its_headline_prints_them():
    result = tiny_result()
    written = _written_flags()
    result.flags = [flag for flag, _ in written]
    assert result.warnings == [flag for flag, warns in written if warns]
    assert result.summary_row()["warned"] is True
    text = headline(result)
    assert all(f"warning: {flag}" in text for flag in result.warnings)
    assert "low acceptance" not in text  # a note stays in the result's flags
    assert "note: low acceptance in 3 walker(s)" in result.summary_table()
    result.flags = ["low acceptance in 3 walker(s)"]
    assert result.warnings == [] and result.summary_row()["warned"] is False
    assert "warning:" not in headline(result)


def test_the_how_to_page_lists_every_kind_as_the_code_sorts_it():
    from pathlib import Path

    page = (Path(__file__).resolve().parents[4] / "docs" / "how-to" / "flags.rst").read_text()
    rows = page.split(".. list-table::")[1]
    for kind, what in FLAG_KINDS.items():
        entry = rows.split(f"   * - ``{kind}``")[1].split("\n")[1]
        assert entry.strip() == f"- {'warning' if what.warning else 'note'}", kind
