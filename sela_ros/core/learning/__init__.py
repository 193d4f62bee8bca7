"""SELA-ADAPT and its parts: the GPs over the archive, UCB, the motion models, the damage
priors and their mixture, the fall risk, the parameters."""
from sela_ros.core.learning.damage_priors import (
    DamagePriorError,
    DamagePriors,
    params_checksum,
    priors_path,
    resolve_priors,
)
from sela_ros.core.learning.fall_risk import FallRisk
from sela_ros.core.learning.gp import CandidateSetGP, exponential_kernel
from sela_ros.core.learning.motion import PointMotion, SE2Motion
from sela_ros.core.learning.sela import SELA, Decision, observed_generic_reward
from sela_ros.core.learning.sela_config import AUTO, NONE, SELAConfig

__all__ = ['AUTO', 'NONE', 'SELA', 'CandidateSetGP', 'DamagePriorError', 'DamagePriors',
           'Decision', 'FallRisk', 'PointMotion', 'SE2Motion', 'SELAConfig',
           'exponential_kernel', 'observed_generic_reward', 'params_checksum', 'priors_path',
           'resolve_priors']
