"""Gain regulation schemes of thesis ch. 4 (Eq 23, VST2 reading, Eq 48–50)."""

from __future__ import annotations

import pytest

from gait_biofeedback.core.orientation.gain_regulation import GainRegulator, switch_level


def test_fixed_ignores_deviations():
    assert GainRegulator("fixed", [0.1]).gain(5.0, 5.0) == 0.1


def test_two_level_needs_both_sensors_quiet():
    r = GainRegulator("two_level", [0.1, 0.01], acc_thresholds=[0.05], mag_thresholds=[0.1])
    assert r.gain(0.01, 0.05) == 0.1
    assert r.gain(0.06, 0.05) == 0.01  # acc disturbed
    assert r.gain(0.01, 0.2) == 0.01  # mag disturbed
    assert r.gain(0.01, None) == 0.1  # 6D: acc condition only
    assert r.level == 0


def test_three_level_middle_band():
    r = GainRegulator("three_level", [1.0, 0.1, 0.01], acc_thresholds=[0.05, 0.2], mag_thresholds=[0.1, 0.3])
    assert r.gain(0.01, 0.01) == 1.0
    assert r.gain(0.1, 0.01) == 0.1 and r.level == 1
    assert r.gain(0.1, 0.5) == 0.01 and r.level == 2
    assert r.gain(0.5, 0.01) == 0.01


def test_switch_level_per_sensor():
    assert switch_level(0.0, [0.5], [0.01, 0.1]) == 0.01
    assert switch_level(0.5, [0.5], [0.01, 0.1]) == 0.1
    assert switch_level(1.0, [0.5, 2.0], [1, 2, 3]) == 2


def test_bad_configuration_raises():
    with pytest.raises(ValueError):
        GainRegulator("fuzzy", [0.1])
    with pytest.raises(ValueError):
        GainRegulator("three_level", [0.1, 0.01], [0.1, 0.2], [0.1, 0.2])
    with pytest.raises(ValueError):
        GainRegulator("two_level", [0.1, 0.01])
