"""Export of a posterior to ArviZ (skipped where arviz is not installed)."""

import numpy as np
import pytest
from tiny_results import tiny_result

from lidarinv.export import read_inference_data, to_inference_data


def test_posterior_exports_to_arviz_with_its_samples_and_units(tmp_path):
    arviz = pytest.importorskip("arviz")
    result = tiny_result(shot_id=7)
    path = tmp_path / "post.h5"
    result.save(path, name="shot_7")
    idata = read_inference_data(path, "shot_7")
    assert isinstance(idata, arviz.InferenceData)
    np.testing.assert_array_equal(idata.posterior["cover"].values[0], result.column("cover"))
    np.testing.assert_array_equal(idata.posterior["rh98"].values[0], result.column("rh98"))
    assert idata.posterior["top_height"].dims == ("chain", "draw")
    np.testing.assert_array_equal(idata.sample_stats["lp"].values[0], result.log_prob)
    np.testing.assert_array_equal(idata.observed_data["height"].values, result.axis)
    assert idata.attrs["shot_id"] == "7" and '"top_height": "m"' in idata.attrs["units"]
    summary = arviz.summary(idata, var_names=["cover"], kind="stats", hdi_prob=0.9)
    assert summary.loc["cover", "mean"] == pytest.approx(result.column("cover").mean(), rel=1e-3)


def test_a_missing_arviz_says_how_to_install_it(monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_arviz(name, *args, **kwargs):
        if name == "arviz":
            raise ImportError("No module named 'arviz'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_arviz)
    with pytest.raises(ImportError, match=r"lidarinv\[arviz\]"):
        to_inference_data(tiny_result())
