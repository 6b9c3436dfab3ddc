"""The ``lidarinv simulate`` command end to end."""

import numpy as np
import pytest

from forward.examples import example
from lidarinv.cli import main
from lidarinv.io.simulation import read_simulation


def test_simulate_example_writes_documented_layout(tmp_path, capsys):
    out = tmp_path / "jp.h5"
    assert (
        main(
            [
                "simulate",
                "--example",
                "jack-pine",
                "-o",
                str(out),
                "--plot",
                str(tmp_path / "jp.png"),
            ]
        )
        == 0
    )
    records = read_simulation(out)
    assert len(records) == 9
    first = records[0]
    for name in ("height", "samples", "canopy", "ground", "gap", "crown_volume"):
        assert first[name].shape == first["height"].shape
    np.testing.assert_allclose(first["samples"], first["canopy"] + first["ground"])
    assert first["samples"].sum() == pytest.approx(
        first["canopy_energy"] + first["ground_energy"], rel=1e-6
    )
    assert (tmp_path / "jp.png").stat().st_size > 10_000
    assert "wrote 9 waveform(s)" in capsys.readouterr().out


def test_flags_override_the_preset(tmp_path):
    stems = tmp_path / "stems.csv"
    example("jack-pine").stand.subset(slice(0, 200)).to_csv(stems)
    out = tmp_path / "o.h5"
    args = [
        "simulate",
        str(stems),
        "--instrument",
        "lvis",
        "--footprint-sigma",
        "3",
        "--pulse-fwhm",
        "6",
        "--rho-g",
        "0.5",
        "--hotspot-k",
        "1.5",
        "--center",
        "20",
        "20",
        "-o",
        str(out),
    ]
    assert main(args) == 0
    import h5py

    with h5py.File(out) as handle:
        assert handle.attrs["instrument"] == "lvis"
        assert handle.attrs["footprint_sigma_m"] == 3.0
        assert handle.attrs["pulse_fwhm_ns"] == 6.0
        assert handle.attrs["hotspot_k"] == 1.5
        assert handle.attrs["ground_reflectance"] == 0.5
        assert handle["stand/x"].shape == (200,)


def test_bad_stem_map_gives_a_clean_error(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y,height,crown_length,crown_radius,shape,favd\n0,0,10,4,1,sphere,0.5\n")
    assert main(["simulate", str(bad), "-o", str(tmp_path / "o.h5")]) == 2
    assert "unknown crown shape" in capsys.readouterr().err
