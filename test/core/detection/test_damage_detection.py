"""The damage detector core: fires on a drop, not on learning in progress."""
import math

import pytest

from sela_ros.core.detection.damage_detection import (
    DamageDetector,
    DetectorConfig,
    prediction_error,
)


def test_error_combines_position_and_heading():
    assert prediction_error([0, 0, 0], [0.3, 0.4, 0], 0.2) == pytest.approx(0.5)
    assert prediction_error([0, 0, 0], [0, 0, 1.0], 0.2) == pytest.approx(0.2)
    # heading error wraps: 3.1 vs -3.1 rad is 0.083 rad apart, not 6.2
    assert prediction_error([0, 0, 3.1], [0, 0, -3.1], 1.0) == pytest.approx(
        2 * math.pi - 6.2)


def test_fires_when_window_mean_exceeds_threshold_then_cools_down():
    det = DamageDetector(DetectorConfig(threshold=0.25, window=2, cooldown=2, yaw_weight=0))
    assert not det.observe([0, 0, 0], [0.4, 0, 0]).fire      # window not full yet
    assert det.observe([0, 0, 0], [0.4, 0, 0]).fire          # mean 0.4 > 0.25
    assert not det.observe([0, 0, 0], [0.5, 0, 0]).fire      # cooling down
    assert not det.observe([0, 0, 0], [0.5, 0, 0]).fire
    assert det.observe([0, 0, 0], [0.5, 0, 0]).fire
    assert det.detections == 2


def test_small_errors_never_fire():
    det = DamageDetector(DetectorConfig(threshold=0.25, window=2, cooldown=0))
    assert not any(det.observe([0.2, 0, 0], [0.3, 0.05, 0.1]).fire for _ in range(20))


def test_only_confident_predictions_are_judged():
    det = DamageDetector(DetectorConfig(threshold=0.25, window=2, cooldown=0, max_sigma=0.1))
    verdict = det.observe([0, 0, 0], [0.9, 0, 0], sigma=0.4)  # a gait still being learned
    assert not verdict.fire and not verdict.judged
    assert not det.observe([0, 0, 0], [0.5, 0, 0], sigma=0.05).fire  # window not full
    assert not det.observe([0, 0, 0], [0.9, 0, 0], sigma=1.0).judged
    assert det.observe([0, 0, 0], [0.5, 0, 0], sigma=0.02).fire  # two known gaits off


@pytest.mark.parametrize('kwargs', [{'threshold': -1}, {'threshold': math.nan},
                                    {'window': 0}, {'window': 1.5}, {'cooldown': -1},
                                    {'max_sigma': math.inf}])
def test_bad_config_is_a_clear_error(kwargs):
    with pytest.raises(ValueError, match='detection.'):
        DetectorConfig(**kwargs)


def test_non_finite_outcome_is_rejected():
    with pytest.raises(ValueError, match='non-finite'):
        DamageDetector().observe([0, 0, 0], [math.nan, 0, 0])


@pytest.mark.parametrize('predicted, observed', [
    ([0, 0, 1e308], [0, 0, -1e308]),            # the yaw difference overflows
    ([1e308, -1e308, 0], [-1e308, 1e308, 0]),   # so does the position difference
    ([0, 0, -1.7976931348623157e308], [0, 0, 1.7976931348623157e308]),
])
def test_finite_values_whose_difference_overflows_are_judged_not_raised(predicted, observed):
    error = prediction_error(predicted, observed, 0.2)
    assert error >= 0 and not math.isnan(error)
    verdict = DamageDetector(DetectorConfig(window=1)).observe(predicted, observed)
    assert verdict.judged and not math.isnan(verdict.error)


def test_wrapped_heading_error_matches_the_plain_one_for_ordinary_values():
    for a, b in ((0.3, -0.2), (3.0, -3.0), (10.0, -7.0), (-1e6, 2.5)):
        expected = abs(math.remainder(b - a, 2 * math.pi))
        assert prediction_error([0, 0, a], [0, 0, b], 1.0) == pytest.approx(expected, abs=1e-6)
