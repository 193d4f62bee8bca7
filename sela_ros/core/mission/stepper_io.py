"""What the mission stepper takes (events) and gives (commands), and its state. ROS-free.

The driver of a :class:`sela_ros.core.mission.MissionStepper` (the ``sela_adapter`` node,
:func:`sela_ros.core.mission.run_mission`, a test) turns what it observes into the events
below and carries out the commands the stepper returns. Poses are ``(x, y, yaw)`` in the
odom frame, times in seconds.
"""
import enum
from dataclasses import asdict, dataclass

import numpy as np

from sela_ros.core.learning import Decision

# --- events (what the driver observed) -----------------------------------------------------


@dataclass(frozen=True)
class GoalReceived:
    goal: tuple  # (x, y) in the odom frame


@dataclass(frozen=True)
class GoalsReceived:
    """A mission of several goals, visited in order (a ``nav_msgs/Path`` on ``goal_path``,
    as waypoint followers take it); learning carries from one goal to the next."""

    goals: tuple  # ((x, y), ...) in the odom frame


@dataclass(frozen=True)
class PoseObserved:
    pose: tuple  # (x, y, yaw): odometry
    stamp: float = None  # its time (s, the simulator's clock); None: unknown


@dataclass(frozen=True)
class PlanReceived:
    """The planner's answer: the whole path to the goal (``path``, as ``nav_msgs/GetPlan``
    gives it), from which the stepper takes the waypoints as the step starts
    (``planner.lookahead`` along it, or :mod:`~sela_ros.core.mission.reach`'s);
    or, from a driver that only has one, the ``waypoint`` itself. Neither: no path
    (``reason`` says why)."""

    step: int  # the ``step`` of the RequestPlan it answers
    start: tuple  # the ``start`` of that request
    waypoint: tuple = None
    reason: str = ''
    path: tuple = None  # ((x, y), ...) from the start to the goal


@dataclass(frozen=True)
class OutcomeReceived:
    behavior_id: int
    generic_reward: tuple  # observed (dx, dy, dyaw)
    end_pose: tuple  # observed (x, y, yaw) after the gait
    fallen: bool = False
    stamp: float = None  # the simulator's time at the end of the gait
    true_pose: tuple = None  # in process only: what really happened (for the record)
    # The gait started standing, settled (BehaviorOutcome.standing_start); None: not said.
    standing_start: bool | None = None
    # observed (x, y, yaw) before the gait, as the outcome says: its generic reward must match
    # it and end_pose; None: not said (the pose the step was planned from is checked instead).
    start_pose: tuple = None
    # each foot's share of the gait on the ground (the legs' order of the robot); None: not
    # measured. What the self-model reads (sela_ros.core.learning.self_model).
    duty_factors: tuple = None


@dataclass(frozen=True)
class DamageSimulated:
    """The outcomes of a :class:`SimulateDamage`: each gait's generic reward ``(n, k)`` and
    fall ``(n,)`` on the robot's simulator; ``error``: why there are none."""

    damage: str
    gaits: tuple
    generic_reward: tuple = ()
    fallen: tuple = ()
    error: str = ''
    asked: str = ''  # the damage requested, if the feet settled on a smaller one ('': the same)


@dataclass(frozen=True)
class VerdictReceived:
    behavior_id: int
    fire: bool  # damage detected: adapt
    error: float = float('nan')  # the prediction error (m), for the record
    threshold: float = float('nan')  # the detector's, for the record


@dataclass(frozen=True)
class AdaptRequested:
    """A user (``~/adapt``) asks to start or restart adaptation."""


@dataclass(frozen=True)
class ClearRequested:
    """A user (``~/clear``) asks to forget what was learned."""


@dataclass(frozen=True)
class CancelRequested:
    """A client cancels the mission: it ends after the running gait (at once when none
    runs), with code ``canceled``."""

    reason: str = 'canceled'


@dataclass(frozen=True)
class ResetDone:
    success: bool
    message: str = ''


@dataclass(frozen=True)
class HoldChanged:
    """No gait may be sent while ``reason`` is not None (e.g. the archive does not match the
    simulator); '' holds silently (a check in progress)."""

    reason: str = None


@dataclass(frozen=True)
class Tick:
    """Time passes: catches time-outs."""


# --- commands (what the driver must do) ----------------------------------------------------

class Level(enum.IntEnum):
    """Severity, with diagnostic_msgs/DiagnosticStatus's values."""

    OK = 0
    WARN = 1
    ERROR = 2


@dataclass(frozen=True)
class RequestPlan:
    step: int
    start: np.ndarray  # (x, y, yaw)
    goal: np.ndarray  # (x, y)


@dataclass(frozen=True)
class SendGait:
    behavior_id: int
    index: int  # of the archive's behaviour
    predicted_gr: np.ndarray
    sigma: float  # how unsure the prediction is (0 while the map is trusted)
    resend: bool = False  # the same command again (its outcome never came)
    # Why, for observers (markers): the pose it was chosen from, the waypoint, and the best
    # candidates (rows x, y, sigma, ucb; the chosen first). None on a resend.
    pose: tuple = None
    waypoint: tuple = None
    candidates: np.ndarray = None


@dataclass(frozen=True)
class SimulateDamage:
    """Simulate ``damage`` (a damage spec) on the map's ``gaits``, each from a standing
    start, beside the mission; the answer is a :class:`DamageSimulated` (the self-model:
    :func:`sela_ros.core.mission.answer_request` runs it). ``feet``: the self-model's
    evidence (``LostLegs``), which may settle on a smaller damage first."""

    damage: str
    gaits: tuple
    feet: object = None


@dataclass(frozen=True)
class RequestReset:
    """Put the fallen robot back at the start (``sim_bridge/reset``)."""


@dataclass(frozen=True)
class PublishReward:
    value: float  # the specialised reward observed: -||waypoint - end xy||


@dataclass(frozen=True)
class PublishStatus:
    level: Level
    message: str
    values: dict  # str -> str: the mission status (see :meth:`MissionStepper.status`)


@dataclass(frozen=True)
class Report:
    """Say it: in the log, and on diagnostics when ``level`` is ERROR."""

    level: Level
    message: str


@dataclass(frozen=True)
class Reply:
    """The answer to an AdaptRequested or ClearRequested."""

    success: bool
    message: str


@dataclass(frozen=True)
class SaveState:
    """Write :meth:`MissionStepper.snapshot` (taken now) to the state file."""

    snapshot: dict


#: Why a mission ended (:attr:`MissionEnded.code`).
END_CODES = ('succeeded', 'max_steps', 'no_plan', 'canceled', 'preempted', 'failed')


@dataclass(frozen=True)
class MissionEnded:
    """A mission ended: said exactly once per mission, whatever ended it, after the save
    that records it (a driver releases it once that save is on disk, as it does statuses).

    ``code`` is one of :data:`END_CODES`; ``reason`` says it in words; ``steps`` were taken
    toward the last goal, ``goals_reached`` of the mission's ``goals``."""

    mission_id: int
    success: bool
    code: str
    reason: str
    steps: int
    pose: tuple = None  # where the robot was (x, y, yaw), if known
    goals_reached: int = 0
    goals: int = 1


class State(enum.Enum):
    IDLE = 'idle'  # no goal
    READY = 'ready'  # a goal: the next step starts once there is a pose and no hold
    PLANNING = 'planning'  # waiting for the step's waypoint
    EXECUTING = 'executing'  # gait sent, waiting for its outcome
    VERDICT = 'verdict'  # outcome processed, waiting for the detector's verdict on it
    RESETTING = 'resetting'  # the robot fell: waiting for the reset's answer
    DONE = 'done'  # goal reached, or max_steps spent


@dataclass(frozen=True)
class StepperConfig:
    """Timings (s) and rules of the step cycle (the ``sela_adapter`` parameters)."""

    max_steps: int = 100
    outcome_timeout: float = 10.0  # then the same command is sent again
    # Sends of one command with no outcome at all before the mission fails (the simulator
    # or the robot is not answering).
    outcome_attempts: int = 6
    # Steps in a row whose outcome was refused (implausible, or from elsewhere than the pose
    # the step was planned from) before the mission fails: each is followed by a fresh plan
    # from where odometry puts the robot.
    max_refused_steps: int = 3
    detector_timeout: float = 2.0  # then the next step starts without the verdict
    plan_timeout: float = 10.0  # then the plan is asked again
    plan_attempts: int = 3  # plans asked without an answer before the mission fails
    # Learn from the first step (SELA-ADAPT from the start, as in the paper's experiments);
    # False: trust the map until the damage detector fires (measured: docs/notebook.md).
    adapt_on_start: bool = True
    # A fall is got up from where the robot lies (the simulator rights it); True: the robot
    # is put back at the start through a reset service (episodic set-ups).
    reset_on_fall: bool = False
    pose_tolerance: float = 0.1  # m: odometry this far from the held pose replaces it
    on_detection: str = 'evidence'  # a detection while adapting: see learning.ON_DETECTION
    max_displacement: float = 2.0  # m: an outcome moving the robot further is refused
    # Observations (generic rewards, falls) kept over a robot's life, the latest: what a
    # state file holds and start-up replays is bounded (docs/reliability.md).
    max_observations: int = 1000


@dataclass
class StepRecord:
    """One mission step, as printed by the demo and stored in its summary."""

    step: int
    behavior_index: int
    pose: list
    waypoint: list
    predicted_gr: list
    observed_gr: list
    reward: float
    sigma: float
    adapting: bool
    error: float = float('nan')
    detected: bool = False
    fallen: bool = False
    true_pose: list = None

    def to_dict(self):
        return asdict(self)


@dataclass
class AskedPlan:
    """The plan asked for (one at a time), and its answer once it comes."""

    step: int
    start: np.ndarray
    t: float  # when it was asked
    waypoint: np.ndarray = None
    refused: str = None  # why there is no path
    following: np.ndarray = None  # the waypoint of the step after (planner.horizon 2)
    attempts: int = 1  # times asked
    path: np.ndarray = None  # (n, 2) the planner's answer, its waypoints taken as the step starts

    def answered(self):
        return self.waypoint is not None or self.path is not None


@dataclass
class PendingStep:
    """The step in flight: filled in as it goes through the cycle."""

    step: int
    pose: np.ndarray  # where it starts
    t_start: float
    deadline: float
    waypoint: np.ndarray = None
    decision: Decision = None
    behavior_id: int = None
    t_sent: float = None
    t_outcome: float = None
    record: StepRecord = None
    sends: int = 1  # times the command was sent
    refused: str = None  # why the latest outcome for it was refused
