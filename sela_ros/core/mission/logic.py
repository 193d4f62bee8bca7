"""The learning half of a mission: decide, record and learn, adapt. ROS-free.

:class:`MissionLogic` wraps SELA with what the paper's outer loop adds: the intact map is
trusted (nothing learnt, predictions fully sure) until adaptation starts; adaptation starts
from the outcome that revealed the damage, and restarts on a new damage, from the steps that
showed it; what was learned before is set aside (kept in the state), never deleted.
"""
from collections import deque

import numpy as np

from sela_ros.core.detection import EvidenceConfig
from sela_ros.core.learning import AUTO, SELA, SE2Motion, SELAConfig
from sela_ros.core.mission.stepper_io import StepperConfig, StepRecord


def archive_config(archive, config=None) -> SELAConfig:
    """SELA parameters for ``archive``: ``config`` (dotted names), where ``gp.kernel.sigma``,
    ``fall.kernel.sigma`` and ``planner.horizon`` left out (or ``auto``) are the archive's own
    (:attr:`~sela_ros.core.storage.Archive.kernel_sigma`,
    :attr:`~sela_ros.core.storage.Archive.fall_kernel_sigma`,
    :attr:`~sela_ros.core.storage.Archive.planner_horizon`)."""
    config = dict(config or {})
    own = {'gp.kernel.sigma': archive.kernel_sigma,
           'fall.kernel.sigma': getattr(archive, 'fall_kernel_sigma', AUTO),
           'planner.horizon': getattr(archive, 'planner_horizon', 1)}
    for name, value in own.items():
        if config.get(name, AUTO) in (AUTO, None):
            config[name] = value
    return SELAConfig.from_dict(config)


def make_sela(archive, config=None, priors=None):
    """A SE(2) SELA over the archive's behaviours (prior mean: the intact robot's GR), with
    :func:`archive_config`; the fall model takes the archive's
    :attr:`~sela_ros.core.storage.Archive.stability` when it has one; ``priors``: damage
    priors for these behaviours (:mod:`sela_ros.core.learning.damage_priors`) or None."""
    return SELA(archive.normalised_descriptors(), archive.generic_reward, SE2Motion(),
                config=archive_config(archive, config),
                stability=getattr(archive, 'stability', None), priors=priors)


def following_waypoint(pose, waypoint, goal):
    """The waypoint of the step after the one toward ``waypoint``, when only that waypoint
    is known (the planner node answers with the path to it): as far again in the same
    direction, not past the goal; None when ``waypoint`` is the goal."""
    pose, waypoint, goal = (np.asarray(v, dtype=float).reshape(-1)[:2]
                            for v in (pose, waypoint, goal))
    step, left = waypoint - pose, float(np.linalg.norm(goal - waypoint))
    length = float(np.linalg.norm(step))
    if left < 1e-6 or length < 1e-9:
        return None
    return waypoint + step / length * min(length, left)


#: What a detection does to what was learned while adapting (``adaptation.on_detection``).
ON_DETECTION = ('reset', 'keep', 'evidence')
#: Steps whose records a mission keeps in memory (the latest); a record is about 1 kB.
RECORDS_KEPT = 10_000


class MissionLogic:
    """The learning half of a mission: decide, record and learn, adapt.

    Args:
        sela: the SELA learner over the archive.
        adapt_on_start: learn from the first step instead of waiting for the detector.
        reset_on_fall: a step that ends fallen is followed by a reset to the start, so the
            gait took the robot nowhere: it is learnt as a zero displacement (learning the
            tumble's displacement instead would make a gait that falls toward the goal look
            good, and the robot would try it again and again from the start).
        keep_records: how many of the latest steps' records ``records`` keeps.
    """

    def __init__(self, sela, adapt_on_start=False, reset_on_fall=False,
                 on_detection=StepperConfig.on_detection, evidence=None,
                 keep_records=RECORDS_KEPT):
        if on_detection not in ON_DETECTION:
            raise ValueError(f'adaptation.on_detection must be one of {ON_DETECTION}, got '
                             f'{on_detection!r}')
        self.sela = sela
        self.on_detection = on_detection
        self.evidence_config = evidence or EvidenceConfig()
        self.evidence = None  # the latest change_evidence() weighed ('evidence' only)
        self.restarts = 0
        self.reset_on_fall = bool(reset_on_fall)
        self.adapting = bool(adapt_on_start)
        self.adaptations = 1 if adapt_on_start else 0
        self.last = None  # (index, learnt generic reward, standing start) of the latest step
        # Whether the next step starts standing: after a fall and the reset that follows it
        # (reset_on_fall). Unknown at start-up (the robot may have walked): not claimed.
        self.standing_next = False
        # The latest steps (a robot's life is not kept in memory: the state file keeps
        # what was learnt); ``steps`` counts them all.
        self.records = deque(maxlen=keep_records)
        self.steps = 0

    def decide(self, pose, waypoint, goal=None, following=None):
        """The behaviour to execute from ``pose`` toward ``waypoint``; SELA may look one
        step further (``planner.horizon`` 2) toward ``following``, the waypoint after it on
        the path, or, with only ``goal`` known, :func:`following_waypoint`."""
        if following is None and goal is not None:
            following = following_waypoint(pose, waypoint, goal)
        return self.sela.ask(np.asarray(pose, dtype=float), waypoint=waypoint,
                             next_waypoint_xy=following, map_trusted=not self.adapting)

    def outcome(self, decision, pose, observed_gr, fallen=False, true_pose=None,
                standing_start=None):
        """Record the outcome of ``decision`` and learn from it when adapting.

        ``standing_start``: the gait started from the robot standing, settled (as the
        damage priors' tables ran every gait); None (not said): after a fall and its reset
        only."""
        observed_gr = np.asarray(observed_gr, dtype=float)
        learnt = np.zeros_like(observed_gr) if fallen and self.reset_on_fall else observed_gr
        self.sela.tell_fall(decision.index, bool(fallen))
        if standing_start is None:
            standing_start = self.standing_next
        self.last = (decision.index, learnt, bool(standing_start))
        if self.adapting:
            self.sela.tell(*self.last)
        self.standing_next = bool(fallen) and self.reset_on_fall
        record = StepRecord(
            step=self.steps + 1, behavior_index=int(decision.index),
            pose=np.asarray(pose, float).tolist(), waypoint=decision.waypoint.tolist(),
            predicted_gr=decision.predicted_gr.tolist(), observed_gr=observed_gr.tolist(),
            reward=float(decision.reward), sigma=float(decision.sigma),
            adapting=self.adapting, fallen=bool(fallen),
            true_pose=None if true_pose is None else np.asarray(true_pose, float).tolist())
        self.records.append(record)
        self.steps += 1
        return record

    def judged(self, error):
        """The detector's verdict on the latest step: its prediction error (m), for the
        record."""
        if self.records:
            self.records[-1].error = error

    def prediction_sigma(self, decision):
        """How unsure the prediction of ``decision`` is: 0 while the map is trusted."""
        return float(decision.sigma) if self.adapting else 0.0

    def adapt(self):
        """Start adaptation, or decide what to keep when it was running (``on_detection``).

        Returns whether what was learned was kept (False: restarted from the latest step).
        """
        if self.records:
            self.records[-1].detected = True
        self.adaptations += 1
        if not self.adapting:
            self.adapting = True
            if self.last is not None:
                self.sela.tell(*self.last)
            return True
        count = len(self.sela.observations[0])
        keep_from = self._new_damage()
        if keep_from is None:
            return True  # the latest step is learnt already: nothing to do
        self.restarts += 1
        reason = (self.evidence.describe() if self.evidence is not None
                  else f'adaptation.on_detection {self.on_detection}')
        self.sela.set_aside(reason, keep_from)
        if keep_from >= count and self.last is not None:
            self.sela.tell(*self.last)  # nothing kept: learning starts from the latest step
        return False

    def _new_damage(self):
        """Does the evidence say the robot changed (so that what was learned is wrong)?
        None: no; else the position of the first observation to learn again (those before it
        are set aside)."""
        self.evidence = None
        count = len(self.sela.observations[0])
        if self.on_detection == 'keep':
            return None
        if self.on_detection == 'reset' or self.last is None:
            return count
        # 'evidence': several learnt gaits far from what they did (change_evidence); the
        # steps from the first of them on are the new robot's and are learnt again.
        self.evidence = self.sela.change_evidence(self.evidence_config)
        return self.evidence.first if self.evidence.changed else None

    def restore(self, adapting, adaptations, last):
        """Take back where learning stood (a state file's): adapting or not, how many
        adaptations, and the latest step ``[index, generic reward]`` (or None)."""
        self.adapting = bool(adapting)
        self.adaptations = int(adaptations)
        self.last = None if last is None else (int(last[0]), np.array(last[1], float))

    def forget(self, adapt_on_start):
        """Back to the intact map: every observation forgotten, also what restarts set
        aside (a user's request; after it another archive may be loaded)."""
        self.sela.forget_learning()
        self.adapting = bool(adapt_on_start)
        self.last = None
