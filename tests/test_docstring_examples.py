"""The Examples sections of the main entry points run as doctests and hold."""

import doctest

import pytest

from forward.expected import ExpectedWaveformModel
from forward.explicit import WaveformSimulator
from lidarinv.inference import invert_shot
from lidarinv.observe import analyse

#: The entry points whose docstrings carry an Examples section, by name.
ENTRY_POINTS = {
    "forward.explicit.WaveformSimulator.simulate": WaveformSimulator.simulate,
    "forward.expected.ExpectedWaveformModel": ExpectedWaveformModel,
    "lidarinv.observe.analyse": analyse,
    "lidarinv.inference.invert_shot": invert_shot,
}


def docstring_examples(name, obj):
    """The doctest of ``obj``'s own docstring (not those of its members)."""
    finder = doctest.DocTestFinder(recurse=False)
    return [test for test in finder.find(obj, name, globs={}) if test.examples]


@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
def test_examples_run_and_hold(name):
    tests = docstring_examples(name, ENTRY_POINTS[name])
    assert len(tests) == 1, f"{name} has no Examples section with a doctest"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    failures = []
    runner.run(tests[0], out=failures.append)
    outcome = runner.summarize(verbose=False)
    assert outcome.failed == 0, f"{name}'s Examples failed:\n" + "".join(failures)
    assert outcome.attempted >= 3
