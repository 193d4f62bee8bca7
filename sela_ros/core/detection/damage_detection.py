"""Damage detection: is the robot still doing what its model predicts? (ROS-free)

The paper's outer loop adapts only after a *significant performance drop*. Here the drop is
measured on the generic reward: the error between the displacement a behaviour was
predicted to produce and the displacement observed,

    error = ||(dx, dy)_observed - (dx, dy)_predicted|| + yaw_weight * |wrap(dyaw_o - dyaw_p)|

averaged over the last ``window`` *judged* outcomes. Only predictions the model is sure of
are judged: those whose predictive standard deviation is at most ``max_sigma`` (while the
intact map is trusted, every prediction has sigma 0). The detector fires when the average
exceeds ``threshold``, then stays quiet for ``cooldown`` outcomes. Judging only confident
predictions is what tells the errors of learning in progress (a behaviour never tried on the
damaged robot: large sigma) from a new damage (behaviours the GPs already know, small sigma,
large error).
"""
import math
from collections import deque
from dataclasses import dataclass

from sela_ros.core.geometry import wrap_angle
from sela_ros.core.validation import check_number


@dataclass(frozen=True)
class DetectorConfig:
    """Damage detector parameters (``detection.*`` in config/sela.yaml)."""

    threshold: float = 0.25
    yaw_weight: float = 0.2
    window: int = 2
    cooldown: int = 3
    max_sigma: float = 0.1

    def __post_init__(self):
        for name in ('threshold', 'yaw_weight', 'max_sigma'):
            check_number(f'detection.{name}', getattr(self, name), low=0.0)
        check_number('detection.window', self.window, low=1, integer=True)
        check_number('detection.cooldown', self.cooldown, low=0, integer=True)


@dataclass(frozen=True)
class Verdict:
    """The detector's judgement of one outcome."""

    error: float
    mean_error: float
    fire: bool
    judged: bool = True  # False: the prediction was too uncertain to be judged


def prediction_error(predicted_gr, observed_gr, yaw_weight):
    """The error of one step; finite inputs give a finite or infinite error, never a raise.

    Two finite values can be further apart than the largest float (1e308 and -1e308): the
    position error is then ``inf`` (it is that far off), and each heading is wrapped to
    (-pi, pi] before the difference is taken, so it never overflows.
    """
    dx = float(observed_gr[0]) - float(predicted_gr[0])
    dy = float(observed_gr[1]) - float(predicted_gr[1])
    error = math.hypot(dx, dy)
    if len(predicted_gr) > 2 and len(observed_gr) > 2:
        # Each wrapped first: a huge angle's remainder keeps its precision.
        dyaw = wrap_angle(wrap_angle(float(observed_gr[2])) - wrap_angle(float(predicted_gr[2])))
        error += yaw_weight * abs(dyaw)
    return error


class DamageDetector:
    """Compares predicted and observed generic rewards, one outcome at a time."""

    def __init__(self, config=None):
        self.config = config or DetectorConfig()
        self._errors = deque(maxlen=self.config.window)
        self._since_fire = None  # outcomes seen since the last detection (None: never fired)
        self.detections = 0

    def observe(self, predicted_gr, observed_gr, sigma=0.0):
        """Judge one outcome; returns a :class:`Verdict` (``fire`` means: adapt now).

        Args:
            predicted_gr: the generic reward the behaviour was predicted to produce.
            observed_gr: the generic reward observed.
            sigma: predictive standard deviation of that prediction (0: fully trusted).
        """
        for name, value in (('predicted', predicted_gr), ('observed', observed_gr),
                            ('sigma', [sigma])):
            if any(not math.isfinite(float(v)) for v in value):
                raise ValueError(f'{name} has a non-finite value: {value}')
        error = prediction_error(predicted_gr, observed_gr, self.config.yaw_weight)
        if self._since_fire is not None:
            self._since_fire += 1
        if float(sigma) > self.config.max_sigma:
            mean = sum(self._errors) / len(self._errors) if self._errors else float('nan')
            return Verdict(error=error, mean_error=mean, fire=False, judged=False)
        self._errors.append(error)
        mean_error = sum(self._errors) / len(self._errors)
        cooling = self._since_fire is not None and self._since_fire <= self.config.cooldown
        fire = (len(self._errors) == self.config.window and mean_error > self.config.threshold
                and not cooling)
        if fire:
            self.detections += 1
            self._since_fire = 0
            self._errors.clear()
        return Verdict(error=error, mean_error=mean_error, fire=fire)

    def reset(self):
        self._errors.clear()
        self._since_fire = None
