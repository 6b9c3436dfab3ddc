"""Reading errors name the file in one line; absurd samples are refused per shot."""

import pytest
from gedi_files import gedi_shot, write_gedi

from lidarinv.io import example_file, iter_observations
from lidarinv.io.formats import inspect_file
from lidarinv.observe import Observation, ShotError


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "empty file (0 bytes), not an HDF5 waveform file"),
        (b"shot,height\n1,20\n", "not an HDF5 file (no HDF5 signature; it holds text)"),
        (b"\x89\xff\x00binary", "not an HDF5 file (no HDF5 signature; unknown binary content)"),
    ],
)
def test_files_that_are_not_hdf5_are_named(tmp_path, content, message):
    path = tmp_path / "shots.h5"
    path.write_bytes(content)
    for read in (inspect_file, lambda p: list(iter_observations(p))):
        with pytest.raises(ValueError) as error:
            read(path)
        assert str(error.value) == f"{path}: {message}"


def test_a_truncated_file_says_how_much_of_it_is_there(tmp_path):
    whole = example_file("gedi-l1b").read_bytes()
    path = tmp_path / "part.h5"
    path.write_bytes(whole[: len(whole) // 3])
    with pytest.raises(ValueError, match=r"truncated: \d+ of its \d+ bytes present") as error:
        inspect_file(path)
    assert str(error.value).startswith(f"{path}: ") and "\n" not in str(error.value)


def test_a_layout_error_names_the_file(tmp_path):
    path = tmp_path / "gedi.h5"
    write_gedi(path, {"BEAM0000": [gedi_shot(1, 300.0)]})
    with pytest.raises(ValueError, match=r"no beam '9999'") as error:
        inspect_file(path, beams=["9999"])
    assert str(path) in str(error.value)
    with pytest.raises(ValueError, match="does not have the lvis-l1b layout"):
        list(iter_observations(path, "lvis-l1b"))


def test_absurd_samples_make_a_shot_error_and_real_ones_pass(tmp_path):
    shots = [gedi_shot(1, 300.0), gedi_shot(2, 300.0), gedi_shot(3, 300.0)]
    shots[1]["rx"][10] = 1e30
    shots[2]["rx"][10:13] = -3e7
    path = tmp_path / "gedi.h5"
    write_gedi(path, {"BEAM0000": shots})
    good, huge, negative = iter_observations(path)
    assert isinstance(good, Observation)
    assert isinstance(huge, ShotError) and "1 absurd sample(s) (up to 1e+30" in huge.reason
    assert isinstance(negative, ShotError) and "3 absurd sample(s)" in negative.reason
    for name in ("gedi-l1b", "lvis-l1b"):  # the real sample files hold none
        assert all(isinstance(o, Observation) for o in iter_observations(example_file(name)))
