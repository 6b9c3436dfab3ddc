"""Metrics that contradict each other are never reported as "ok"."""

import sys

import numpy as np
from closed_canopy import GROUND_Z, closed_canopy_shot

from lidarinv.observe import analyse
from lidarinv.observe.quality import INCONSISTENT, contradictions

FWHM = 1.5  # m, a flat ground's return as the analysis sees it (LVIS-like)


def _rh(rh50, rh98):
    rh = np.linspace(-1.0, rh98 + 1.0, 101)
    rh[50], rh[98] = rh50, rh98
    return rh


def test_a_bare_ground_agrees_with_itself():
    rh = _rh(-0.1, 1.2)
    assert contradictions(energy_below_ground=50.0, total_energy=100.0, rh=rh, cover=0.0,
                          return_fwhm_m=FWHM) == []  # fmt: skip


def test_ground_above_most_energy_and_negative_rh50_are_named():
    failed = contradictions(energy_below_ground=90.0, total_energy=100.0, rh=_rh(-1.8, 25.6),
                            cover=0.0, return_fwhm_m=FWHM)  # fmt: skip
    assert failed == ["ground above most energy", "negative RH50", "cover 0 with tall RH98"]


def test_cover_zero_under_a_tall_rh98_is_named():
    failed = contradictions(energy_below_ground=40.0, total_energy=100.0, rh=_rh(3.0, 25.6),
                            cover=0.0, return_fwhm_m=FWHM)  # fmt: skip
    assert failed == ["cover 0 with tall RH98"]


def test_a_ground_on_the_canopy_is_never_ok(monkeypatch):
    """Without the weak-ground search the closed stand's ground lands on a canopy layer
    (the failure of the Mondah shots): the metrics then contradict each other."""
    module = sys.modules["lidarinv.observe.analyse"]
    monkeypatch.setattr(module, "_weak_ground", lambda *args, **kwargs: None)
    statuses = []
    for seed in range(4):
        result = analyse(closed_canopy_shot(seed))
        if abs(result.ground - GROUND_Z) > 5.0:
            assert result.status == INCONSISTENT and not result.quality
            assert result.reason
        statuses.append(result.status)
    assert INCONSISTENT in statuses
