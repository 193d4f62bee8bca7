"""Drives a MissionStepper on a fake clock and keeps what it says (tests without DDS)."""
import numpy as np

from sela_ros.core.learning import SELA, SE2Motion
from sela_ros.core.mission import MissionStepper
from sela_ros.core.mission.stepper_io import (
    GoalReceived,
    OutcomeReceived,
    PlanReceived,
    PoseObserved,
    RequestPlan,
    SendGait,
    StepperConfig,
    VerdictReceived,
)

FORWARD = (0.2, 0.0, 0.0)


def small_sela():
    rng = np.random.default_rng(0)
    candidates = rng.random((50, 2))
    prior = np.column_stack([candidates * 0.6 - 0.3, np.zeros(50)])
    return SELA(candidates, prior, SE2Motion())


class Driver:
    """Feeds a stepper and keeps what it says; the clock is ``self.now``."""

    def __init__(self, **config):
        # Most of the cycle is about the map trusted until the detector fires.
        config.setdefault('adapt_on_start', False)
        self.stepper = MissionStepper(small_sela(), StepperConfig(**config))
        self.now = 0.0
        self.states = {self.stepper.state}
        self.log = []

    def __call__(self, event, dt=0.0):
        self.now += dt
        out = self.stepper.handle(event, self.now)
        self.states.add(self.stepper.state)
        self.log += out
        return out

    @property
    def state(self):
        return self.stepper.state

    def start(self, goal=(1.0, 0.0), pose=(0.0, 0.0, 0.0)):
        self(PoseObserved(pose, stamp=0.0))
        return only(self(GoalReceived(goal)), RequestPlan)

    def plan(self, request, waypoint=None):
        waypoint = request.start[:2] + (0.3, 0.0) if waypoint is None else waypoint
        return self(PlanReceived(request.step, tuple(request.start), tuple(waypoint)))

    def outcome(self, gait, gr=FORWARD, fallen=False, stamp=None):
        end = self.stepper.sela.motion.predict(self.stepper.pending.pose, gr)
        return self(OutcomeReceived(gait.behavior_id, gr, tuple(end), fallen, stamp), dt=3.0)

    def step(self, request, fire=False, gr=FORWARD):
        """One full step from its plan request: returns the next plan request (or None)."""
        gait = only(self.plan(request), SendGait)
        out = self.outcome(gait, gr)
        out += self(VerdictReceived(gait.behavior_id, fire))
        requests = of(out, RequestPlan)
        return requests[0] if requests else None


def of(commands, kind):
    return [c for c in commands if isinstance(c, kind)]


def only(commands, kind):
    found = of(commands, kind)
    assert len(found) == 1, commands
    return found[0]
