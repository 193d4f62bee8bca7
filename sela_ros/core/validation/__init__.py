"""Checks at the edge: numbers and arrays of numbers, and what one gait can do to the robot."""
from sela_ros.core.validation.numeric import check_number, finite_array
from sela_ros.core.validation.plausibility import (
    ImplausibleOutcome,
    OutcomeLimits,
    archive_displacement_limit,
    check_generic_rewards,
    check_outcome,
)

__all__ = ['ImplausibleOutcome', 'OutcomeLimits', 'archive_displacement_limit',
           'check_generic_rewards', 'check_number',
           'check_outcome', 'finite_array']
