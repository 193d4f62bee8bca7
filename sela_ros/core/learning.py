"""The learning half of a mission: decide, record and learn, adapt. ROS-free.

:class:`MissionLogic` wraps SELA with what the paper's outer loop adds: the intact map is
trusted (nothing learnt, predictions fully sure) until adaptation starts; adaptation starts
from the outcome that revealed the damage, and restarts from scratch on a new damage.
"""
import numpy as np

from sela_ros.core.sela import SELA, SE2Motion, SELAConfig
from sela_ros.core.stepper_io import StepRecord


def make_sela(archive, config=None):
    """A SE(2) SELA over the archive's behaviours (prior mean: the intact robot's GR)."""
    return SELA(archive.normalised_descriptors(), archive.generic_reward, SE2Motion(),
                config=SELAConfig.from_dict(dict(config or {})))


class MissionLogic:
    """The learning half of a mission: decide, record and learn, adapt.

    Args:
        sela: the SELA learner over the archive.
        adapt_on_start: learn from the first step instead of waiting for the detector.
        reset_on_fall: a step that ends fallen is followed by a reset to the start, so the
            gait took the robot nowhere: it is learnt as a zero displacement (learning the
            tumble's displacement instead would make a gait that falls toward the goal look
            good, and the robot would try it again and again from the start).
    """

    def __init__(self, sela, adapt_on_start=False, reset_on_fall=False):
        self.sela = sela
        self.reset_on_fall = bool(reset_on_fall)
        self.adapting = bool(adapt_on_start)
        self.adaptations = 1 if adapt_on_start else 0
        self.last = None  # (index, learnt generic reward) of the latest outcome
        self.records = []

    def decide(self, pose, waypoint):
        """The behaviour to execute from ``pose`` toward ``waypoint``."""
        return self.sela.ask(np.asarray(pose, dtype=float), waypoint=waypoint)

    def outcome(self, decision, pose, observed_gr, fallen=False, true_pose=None):
        """Record the outcome of ``decision`` and learn from it when adapting."""
        observed_gr = np.asarray(observed_gr, dtype=float)
        learnt = np.zeros_like(observed_gr) if fallen and self.reset_on_fall else observed_gr
        self.sela.tell_fall(decision.index, bool(fallen))
        if self.adapting:
            self.sela.tell(decision.index, learnt)
        self.last = (decision.index, learnt)
        record = StepRecord(
            step=len(self.records) + 1, behavior_index=int(decision.index),
            pose=np.asarray(pose, float).tolist(), waypoint=decision.waypoint.tolist(),
            predicted_gr=decision.predicted_gr.tolist(), observed_gr=observed_gr.tolist(),
            reward=float(decision.reward), sigma=float(decision.sigma),
            adapting=self.adapting, fallen=bool(fallen),
            true_pose=None if true_pose is None else np.asarray(true_pose, float).tolist())
        self.records.append(record)
        return record

    def prediction_sigma(self, decision):
        """How unsure the prediction of ``decision`` is: 0 while the map is trusted."""
        return float(decision.sigma) if self.adapting else 0.0

    def adapt(self):
        """Start adaptation, or restart it from scratch if it was running."""
        if self.adapting:
            self.sela.reset_learning()
        self.adapting = True
        self.adaptations += 1
        if self.last is not None:
            self.sela.tell(*self.last)
        if self.records:
            self.records[-1].detected = True

    def forget(self, adapt_on_start):
        """Back to the intact map: every observation forgotten."""
        self.sela.reset_learning()
        self.adapting = bool(adapt_on_start)
        self.last = None
