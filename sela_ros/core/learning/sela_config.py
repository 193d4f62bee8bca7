"""SELA's parameters (:class:`SELAConfig`), with the paper's defaults, in one place.

Dotted names (``gp.kernel.sigma``) are the node parameters and the keys of
``config/*.yaml``; :mod:`sela_ros.core.learning.sela` uses them and imports them from here.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from sela_ros.core.learning import acquisition, damage_priors, fall_risk, gp, prior_mixture
from sela_ros.core.validation import check_number


@dataclass(frozen=True)
class SELAConfig:
    """SELA parameters, with the paper's (Appendix) defaults, in one place.

    Dotted names (``gp.kernel.sigma``) are the field names with ``_`` read as ``.``;
    the same names are used in ``config/*.yaml``.
    """

    gp_kernel_sigma: float = gp.DEFAULT_SIGMA
    gp_kernel_variance: float = gp.DEFAULT_VARIANCE
    gp_noise: float = gp.DEFAULT_NOISE
    acquisition_ucb_alpha: float = acquisition.DEFAULT_ALPHA
    # m along the path to the waypoint of the reward (hexapod: docs/hexapod_results.md)
    planner_lookahead: float = 0.6
    # Steps looked ahead: 1, the paper's (the gait landing nearest the waypoint), or 2 (the
    # gait from whose predicted end pose the best next gait lands nearest a second waypoint
    # as far again along the path). Maps set their own (learning.archive_config).
    planner_horizon: int = 1
    goal_eps: float = 0.1
    # Risk of falling accepted (fall-aware acquisition); 1 or more: falls are not avoided.
    fall_risk_threshold: float = fall_risk.DEFAULT_THRESHOLD
    # Kernel length of the fall GP (normalised descriptors); 0: gp.kernel.sigma. Falls are
    # more local than displacements on the 8-D map (docs/notebook.md), so maps set their own.
    fall_kernel_sigma: float = 0.0
    # What a fall costs, in metres of the specialised reward: UCB takes cost x risk off each
    # gait's score (0: only the threshold keeps falls away).
    fall_risk_cost: float = fall_risk.DEFAULT_COST
    # A damage prior (a table of the gaits on a foreseen damage) is used only while its median
    # squared error over the steps seen is below this (units of the chaining error); 0: the
    # tables are never used.
    priors_max_misfit: float = damage_priors.DEFAULT_MAX_MISFIT
    # The same cap for a table that reproduced every step the robot made from a standing
    # start (what the table ran; needs tell(..., standing_start=True)); below priors.max.misfit:
    # no exception.
    priors_max_misfit_reproduced: float = damage_priors.DEFAULT_MAX_MISFIT_REPRODUCED
    # Prior standard deviation of each table's weight in the mixture of damage priors that is
    # the prior mean while no table reproduced the robot's standing starts
    # (:mod:`~sela_ros.core.learning.prior_mixture`); 0: no mixture, the one table that best
    # explains the steps (within priors.max.misfit) or the intact map.
    priors_weights_sd: float = prior_mixture.DEFAULT_WEIGHT_SD

    def __post_init__(self):
        for f in dataclasses.fields(self):
            check_number(_dotted(f.name), getattr(self, f.name), low=0.0,
                         low_open=f.name not in ('acquisition_ucb_alpha', 'gp_noise',
                                                 'fall_kernel_sigma', 'fall_risk_cost',
                                                 'priors_max_misfit',
                                                 'priors_max_misfit_reproduced',
                                                 'priors_weights_sd'))
        if self.planner_horizon not in HORIZONS:
            raise ValueError(f'planner.horizon must be one of {HORIZONS}, got '
                             f'{self.planner_horizon!r}')

    @classmethod
    def keys(cls):
        return [_dotted(f.name) for f in dataclasses.fields(cls)]

    @classmethod
    def from_dict(cls, values: dict) -> SELAConfig:
        """Build from ``{'gp.kernel.sigma': 0.1, ...}``; unknown keys raise ValueError."""
        known = {_dotted(f.name): f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ValueError(f'unknown SELA parameter(s) {unknown}; expected some of '
                             f'{sorted(known)}')
        return cls(**{known[k]: _number(k, v) for k, v in values.items()})

    def to_dict(self) -> dict:
        return {_dotted(k): v for k, v in dataclasses.asdict(self).items()}


def _number(name, value):
    """A parameter's value as a number: an integral one (``planner.horizon: 2``) stays an
    int, so that a dump of the config reads back as it was written."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise ValueError(f'{name} must be a number, got {value!r}') from None
    if name == 'planner.horizon' and float(value).is_integer():
        return int(value)
    return float(value)


#: Steps SELA can look ahead (``planner.horizon``).
HORIZONS = (1, 2)


def _dotted(name):
    return name.replace('_', '.')
