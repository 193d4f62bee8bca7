"""The mission: the step cycle (events in, commands out), the learning half of it, its status
as text, and the loop that drives it in process. The events and commands are in
:mod:`sela_ros.core.mission.stepper_io`."""
from sela_ros.core.mission.in_process import (
    answer_request,
    as_seen_in_odometry,
    run_mission,
    settle_request,
    simulated_answer,
)
from sela_ros.core.mission.logic import ON_DETECTION, MissionLogic, archive_config, make_sela
from sela_ros.core.mission.status import vector_from_text, vector_text
from sela_ros.core.mission.stepper import MissionStepper
from sela_ros.core.mission.stepper_io import Level, State, StepperConfig

__all__ = ['ON_DETECTION', 'Level', 'MissionLogic', 'MissionStepper', 'State',
           'StepperConfig', 'answer_request', 'archive_config', 'as_seen_in_odometry',
           'make_sela', 'settle_request', 'simulated_answer',
           'run_mission', 'vector_from_text', 'vector_text']
