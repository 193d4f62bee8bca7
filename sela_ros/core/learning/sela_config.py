"""SELA's parameters (:class:`SELAConfig`), with the paper's defaults, in one place.

Dotted names (``gp.kernel.sigma``) are the node parameters and the keys of
``config/*.yaml``; :mod:`sela_ros.core.learning.sela` uses them and imports them from here.

Two words stand for what no number can say: :data:`AUTO` (``gp.kernel.sigma``,
``fall.kernel.sigma``, ``planner.horizon``: the archive's own value, which
:func:`sela_ros.core.mission.archive_config` fills in; with no archive, ``fall.kernel.sigma``
auto is ``gp.kernel.sigma``) and :data:`NONE` (``priors.max.misfit``, ``priors.weights.sd``:
that use of the damage priors is off; ``acquisition.caution``: no caution). In a
:class:`SELAConfig` either is None; :meth:`SELAConfig.to_dict` writes the word and
:meth:`SELAConfig.from_dict` reads it.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from sela_ros.core.learning import (
    acquisition,
    damage_priors,
    fall_risk,
    gp,
    prior_mixture,
)
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
    # Prior standard deviation of the logs of the kernel length and signal variance learnt
    # from the steps' residuals by marginal likelihood (sela_ros.core.learning.hyper),
    # centred on gp.kernel.sigma and gp.kernel.variance; None (none): fixed (the paper's).
    gp_hyper_sd: float | None = None
    # Prior standard deviation of the scale and rotation terms of an affine map of the prior
    # mean learnt from the steps (sela_ros.core.learning.affine_mean: what the damage does to
    # every gait), centred on the identity; None (none): the prior mean as it is (the paper's).
    gp_mean_affine: float | None = None
    # Prior standard deviation of the terms of that map's scale linear in the gait's
    # normalised descriptor (affine_mean: on the 8-D map, a leg lost slows the gaits that lean
    # on it most), centred on zero; None (none): one scale for the whole map. Used only with
    # gp_mean_affine.
    gp_mean_descriptor: float | None = None
    acquisition_ucb_alpha: float = acquisition.DEFAULT_ALPHA
    # m: once untried gaits have landed this far from their predictions (rms per axis, learnt
    # from the steps: acquisition.learnt_error), each gait is scored by its expected distance
    # to the waypoint, which prefers gaits whose landing is known; None (none): never, the
    # predicted distance (the paper's).
    acquisition_caution: float | None = acquisition.DEFAULT_CAUTION
    # Weight of the distance off the path against the distance along it: each gait is scored
    # by how far along the planned path (from the robot past the waypoint to the goal) its
    # landing puts the robot, less this times its distance off the path
    # (acquisition.progress_reward); None (none): by its distance to the waypoint (the paper's).
    acquisition_progress: float | None = None
    # m: while caution is on, each gait is scored by the probability that its landing (the
    # landing variance caution computes) falls within this distance of the waypoint, two steps
    # ahead the product of both steps' (acquisition.reach_probability); the expected distance
    # where no gait has a real chance; None (none): caution's expected distance.
    acquisition_reach: float | None = None
    # m along the path to the waypoint of the reward (hexapod: docs/hexapod_results.md)
    planner_lookahead: float = 0.6
    # Multiple of the robot's shown reach (a high quantile of the planar displacements of the
    # steps learnt that stayed up: sela_ros.core.mission.reach) at which the waypoint is set,
    # within [0.15 m, planner_lookahead]; None (none): planner_lookahead (the paper's).
    planner_reach: float | None = None
    # Steps looked ahead: 1, the paper's (the gait landing nearest the waypoint), or 2 (the
    # gait from whose predicted end pose the best next gait lands nearest a second waypoint
    # as far again along the path). Maps set their own (learning.archive_config).
    planner_horizon: int = 1
    goal_eps: float = 0.1
    # Risk of falling accepted (fall-aware acquisition); 1 or more: falls are not avoided.
    fall_risk_threshold: float = fall_risk.DEFAULT_THRESHOLD
    # Kernel length of the fall GP (normalised descriptors); None (auto): gp.kernel.sigma.
    # Falls are more local than displacements on the 8-D map (docs/notebook.md), so maps set
    # their own.
    fall_kernel_sigma: float | None = None
    # What a fall costs, in metres of the specialised reward: UCB takes cost x risk off each
    # gait's score (0: only the threshold keeps falls away).
    fall_risk_cost: float = fall_risk.DEFAULT_COST
    # A damage prior (a table of the gaits on a foreseen damage) is used only while its median
    # squared error over the steps seen is below this (units of the chaining error); None
    # (none): no table is used on its own.
    priors_max_misfit: float | None = damage_priors.DEFAULT_MAX_MISFIT
    # The same cap for a table that reproduced the steps the robot made from a standing
    # start (what the table ran; needs tell(..., standing_start=True); a third of them or
    # more: damage_priors.REPRODUCED_SHARE); below priors.max.misfit: no exception.
    priors_max_misfit_reproduced: float = damage_priors.DEFAULT_MAX_MISFIT_REPRODUCED
    # Prior standard deviation of each table's weight in the mixture of damage priors that is
    # the prior mean while no table reproduced the robot's standing starts
    # (:mod:`~sela_ros.core.learning.prior_mixture`); None (none): no mixture, the one table
    # that best explains the steps (within priors.max.misfit) or the intact map.
    priors_weights_sd: float | None = prior_mixture.DEFAULT_WEIGHT_SD

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if value is None and _dotted(f.name) in WORDS:
                continue
            check_number(_dotted(f.name), value, low=0.0,
                         low_open=f.name not in ('acquisition_ucb_alpha', 'gp_noise',
                                                 'fall_risk_cost',
                                                 'priors_max_misfit_reproduced'))
        if self.planner_horizon not in HORIZONS:
            raise ValueError(f'planner.horizon must be one of {HORIZONS}, got '
                             f'{self.planner_horizon!r}')

    @classmethod
    def keys(cls):
        return [_dotted(f.name) for f in dataclasses.fields(cls)]

    @classmethod
    def from_dict(cls, values: dict) -> SELAConfig:
        """Build from ``{'gp.kernel.sigma': 0.1, 'priors.weights.sd': 'none', ...}``; unknown
        keys, and ``auto`` where no archive resolved it, raise ValueError."""
        known = {_dotted(f.name): f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ValueError(f'unknown SELA parameter(s) {unknown}; expected some of '
                             f'{sorted(known)}')
        return cls(**{known[k]: _value(k, v) for k, v in values.items()})

    def to_dict(self) -> dict:
        """``{dotted name: value}``, a None written as its word (``auto``, ``none``)."""
        return {_dotted(k): WORDS.get(_dotted(k)) if v is None else v
                for k, v in dataclasses.asdict(self).items()}


#: The word that stands for "the archive's value".
AUTO = 'auto'
#: The word that stands for "off".
NONE = 'none'
#: ``{name: word}`` of the parameters a SELAConfig may hold as None.
WORDS = {'fall.kernel.sigma': AUTO, 'priors.max.misfit': NONE, 'priors.weights.sd': NONE,
         'acquisition.caution': NONE, 'gp.mean.affine': NONE, 'acquisition.progress': NONE,
         'gp.mean.descriptor': NONE, 'planner.reach': NONE,
         'gp.hyper.sd': NONE, 'acquisition.reach': NONE}
#: The parameters whose ``auto`` is the archive's (:func:`sela_ros.core.mission.archive_config`).
ARCHIVE_AUTO = ('gp.kernel.sigma', 'fall.kernel.sigma', 'planner.horizon')


def _value(name, value):
    """A parameter's value: its word (or None) as None where it has one, else a number.
    A 0 for ``none`` reads as none too, so that a state file holding 0 there loads as it
    was meant."""
    word = WORDS.get(name)
    if word is not None and (value is None or value == word
                             or (word == NONE and _is_number(value) and value == 0)):
        return None
    if value == AUTO and name in ARCHIVE_AUTO:
        raise ValueError(f'{name} auto is the archive\'s value: build the config with '
                         'sela_ros.core.mission.archive_config(archive, ...)')
    try:
        return _number(name, value)
    except ValueError:
        if word is None:
            raise
        raise ValueError(f'{name} must be a number or {word}, got {value!r}') from None


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _number(name, value):
    """A parameter's value as a number: an integral one (``planner.horizon: 2``) stays an
    int, so that a dump of the config reads back as it was written."""
    if not _is_number(value):
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
