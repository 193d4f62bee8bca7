"""SELA-ADAPT (Semi-Episodic Learning Algorithm) as an ask/tell object.

One object serves the ROS ``sela_adapter`` node, the in-process experiments and the tests:
``ask(pose)`` runs the reward selection layer (plan, pick a waypoint) and UCB over the whole
archive; ``tell(index, observed_gr)`` adds the observed generic reward to the GPs. Learning
and acting are the same steps: no reset, no separate training phase.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from sela_ros.core.detection import change_evidence
from sela_ros.core.learning import (
    acquisition,
    affine_mean,
    damage_priors,
    fall_risk,
    gp,
    hyper,
    prior_mixture,
)
from sela_ros.core.learning.sela_config import SELAConfig
from sela_ros.core.learning.self_model import PREFIX as SELF_MODEL
from sela_ros.core.planning import next_waypoint, straight_line_planner

#: Steps seen before a second-tier table of the damage priors may be used: the first step of
#: a mission is hedged (a cautious gait that many damages move alike), so one step that a
#: second-tier table reproduced is not enough (docs/learning_the_damage.md, "Two legs lost").
SECOND_TIER_MIN_STEPS = 2


def observed_generic_reward(pose_before, pose_after, motion) -> np.ndarray:
    """``afun`` of the paper: the generic reward observed between two poses."""
    return motion.generic_reward(pose_before, pose_after)


#: With two steps: how many of the best first gaits (by the one-step score) are looked at.
TWO_STEP_CANDIDATES = 40
#: With ``acquisition.reach`` and two steps: of each first gait's next gaits, how many of
#: those expected to land nearest the second waypoint are scored by their chance of reaching.
REACH_SECOND_CANDIDATES = 64
#: How much better (log-likelihood ratio) the affine map of the prior mean must have
#: predicted the steps, each before it was learnt, than the prior mean as it is, to be used.
AFFINE_MIN_SCORE = 0.0
#: With ``gp.hyper.sd``: whether the choice reads the posterior variance of the learnt kernel
#: (True) or of the configured one (False: a GP of that kernel is kept beside, and the learnt
#: kernel sets only the means).
HYPER_VARIANCE_LEARNT = True


@dataclass
class Decision:
    """What :meth:`SELA.ask` chose, and why."""

    index: int
    waypoint: np.ndarray
    predicted_gr: np.ndarray
    predicted_pose: np.ndarray
    # specialised reward: -||waypoint - predicted xy|| (caution: expected; acquisition.progress:
    # the progress along the path beyond the waypoint, acquisition.progress_reward)
    reward: float
    sigma: float   # posterior standard deviation of the chosen behaviour
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    fall_risk: float = 0.0  # predicted risk that the chosen behaviour tips the robot over
    # The best behaviours by UCB, the chosen one first: rows (x, y, sigma, ucb) with (x, y)
    # where each is predicted to land. For observers (RViz markers), not for the choice.
    candidates: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    prior: str = 'intact'  # the prior mean in use: the intact map or a damage prior's name


#: :attr:`Decision.prior` of a first step hedged over the intact map and the damage priors.
HEDGED = 'intact and damage priors'
#: :attr:`Decision.prior` of the damage priors mixed by the weights that fit the steps seen.
MIXTURE = 'mixture of damage priors'


def prior_reason(name) -> str:
    """Why the prior mean ``name`` (:attr:`Decision.prior`) is the one in use, for logs."""
    if name == HEDGED:
        return 'no step has shown the damage yet: the first step is hedged over them'
    if name == MIXTURE:
        return ('no table reproduced the steps from a standing start: the tables weighed '
                'by how well they explain the steps seen')
    if str(name).startswith('self-model '):
        return ("the robot's simulator playing the damage its feet show, which best explains "
                'the steps seen')
    return 'the one that best explains the steps seen'


#: How many candidates a :class:`Decision` reports.
CANDIDATES_SHOWN = 5


def top_candidates(index, x, y, sigma, scores, count=CANDIDATES_SHOWN):
    """Rows ``(x, y, sigma, score)`` of ``index`` then the next best by ``scores``."""
    scores = np.asarray(scores, dtype=float)
    finite = np.flatnonzero(np.isfinite(scores))
    if finite.size > count:
        finite = finite[np.argpartition(-scores[finite], count)[:count]]
    order = [index] + [int(i) for i in finite[np.argsort(-scores[finite], kind='stable')]
                       if i != index]
    order = order[:count]
    return np.column_stack([x[order], y[order], sigma[order], scores[order]])


#: Episodes of learning set aside (:meth:`SELA.set_aside`) kept in the state, the latest.
SET_ASIDE_KEPT = 20


class SELA:
    """SELA-ADAPT over a fixed archive of behaviours.

    Args:
        candidates_normalised: ``(M, d)`` behaviour descriptors in ``[0, 1]^d``.
        prior_gr: ``(M, k)`` generic reward of each behaviour on the intact robot (the
            prior mean of the GPs), ``k == motion.gr_dim``.
        motion: :class:`PointMotion` or :class:`SE2Motion`.
        planner: callable ``(start_xy, goal_xy) -> path (n, 2)`` (e.g. a
            :class:`~sela_ros.core.planning.GridPlanner`); None: the straight line.
        goal: goal ``(x, y)``; may be set later with :meth:`set_goal`.
        config: :class:`SELAConfig` or a dict of dotted names.
        prior_fall_rate: ``(M,)`` fall rate of each behaviour on the robot the archive was
            built on (prior of :class:`~sela_ros.core.learning.FallRisk`); None: zeros.
        stability: ``(M,)`` a feature that makes a behaviour less likely to fall (the 8-D
            hexapod map's support, :attr:`~sela_ros.core.storage.Archive.stability`): the
            risk of untried behaviours is learnt as a logistic model of it; None: one rate.
        priors: :class:`~sela_ros.core.learning.DamagePriors`, the same behaviours on
            foreseen damages: before each choice the prior that best explains the steps seen
            (one table, or their mixture: :meth:`select_prior`) is the GPs' prior mean;
            None: always the intact map.
    """

    def __init__(self, candidates_normalised, prior_gr, motion, planner: Callable | None
                 = None, goal=None, config=None, prior_fall_rate=None, stability=None,
                 priors=None):
        candidates = np.asarray(candidates_normalised, dtype=float)
        prior_gr = np.asarray(prior_gr, dtype=float)
        if candidates.ndim != 2:
            raise ValueError(f'candidates must have shape (M, d), got {candidates.shape}')
        if prior_gr.shape != (candidates.shape[0], motion.gr_dim):
            raise ValueError(f'prior_gr must have shape ({candidates.shape[0]}, '
                             f'{motion.gr_dim}) for {type(motion).__name__}, got '
                             f'{prior_gr.shape}')
        if candidates.size and (candidates.min() < -1e-9 or candidates.max() > 1 + 1e-9):
            raise ValueError('candidates must be normalised to [0, 1]^d')
        if isinstance(config, dict):
            config = SELAConfig.from_dict(config)
        self.config = config or SELAConfig()
        self.motion = motion
        self.planner = planner or straight_line_planner
        self._candidates = candidates
        self._prior = prior_gr
        self._prior_fall_rate = prior_fall_rate
        self._stability = stability
        if priors is not None and (priors.num_candidates != candidates.shape[0]
                                   or priors.generic_reward.shape[2] < motion.gr_dim):
            raise ValueError(f'damage priors are for {priors.num_candidates} behaviours with '
                             f'{priors.generic_reward.shape[2]} outputs, this SELA has '
                             f'{candidates.shape[0]} with {motion.gr_dim}')
        self.priors = priors
        self.set_aside_learning = []  # earlier learning set aside: see set_aside()
        self.goal = None
        if goal is not None:
            self.set_goal(goal)
        self.reset_learning()
        self.forget_falls()

    @property
    def priors(self):
        """The damage priors (:class:`~sela_ros.core.learning.DamagePriors`) or None."""
        return self._priors

    @priors.setter
    def priors(self, priors):
        self._priors = priors
        self._support = {}  # the fall model's prior per table (FallRisk.table_support)
        self._mixture_fit = None  # fitted to other tables
        self._tier = (None, None)  # (the steps it was chosen on, the tables in use)

    def _tables(self):
        """The damage priors in use (None: none): the first tier
        (:meth:`DamagePriors.first_tier`) until a second-tier table is the one that best
        explains the steps and has reproduced the robot's standing starts, then all of
        them. The second tier (the damage library's tables) is never mixed nor hedged
        over: on a damage it does not hold it would only add ways to fit the steps by
        chance (docs/learning_the_damage.md, "The whole library as the second tier")."""
        priors = self._priors
        if priors is None or not priors.second_tier.any():
            return priors
        fall_idx, fallen = self._fall.observations
        idx, grs = self.observations
        key = (idx.tobytes(), grs.tobytes(), fall_idx.tobytes(), fallen.tobytes(),
               tuple(self._standing))
        if self._tier[0] != key:
            use = priors.first_tier()
            if self._gp.num_samples >= SECOND_TIER_MIN_STEPS:
                selection = priors.select(self._prior, idx, grs, fall_idx, fallen,
                                          self.config.priors_max_misfit, self._standing,
                                          self.config.priors_max_misfit_reproduced)
                if selection.index is not None and selection.reproduced \
                        and priors.second_tier[selection.index]:
                    use = priors
            if use is not self._tier[1]:
                self._mixture_fit = None
            self._tier = (key, use)
        return self._tier[1]

    @property
    def num_candidates(self) -> int:
        return self._candidates.shape[0]

    @property
    def gp(self) -> gp.CandidateSetGP:
        return self._gp

    @property
    def fall_risk(self) -> fall_risk.FallRisk:
        return self._fall

    def reset_learning(self) -> None:
        """Forget every observed generic reward: back to the prior (the intact map).

        What was learnt about falls stays (see :meth:`forget_falls`): a gait that tipped this
        robot over is no safer because adaptation restarts.
        """
        c = self.config
        self._gp = gp.CandidateSetGP(self._candidates, self._prior, sigma=c.gp_kernel_sigma,
                                     variance=c.gp_kernel_variance, noise=c.gp_noise)
        # The configured kernel's GP, beside a learnt one (HYPER_VARIANCE_LEARNT False).
        self._gp_configured = None
        self._standing = []  # per observation: did the step start from a standing start?
        # How well each way of using the damage priors predicted every step before it was
        # learnt (log-likelihoods, :meth:`_score_priors`): one table (or the intact map), and
        # the mixture of the tables.
        self._prior_scores = {'table': 0.0, 'mixture': 0.0}
        # How much better the affine map of the prior mean (gp.mean.affine) predicted every
        # step before it was learnt than the prior mean as it is (log-likelihood ratio): the
        # map is used only while it predicts better.
        self._affine_score = 0.0
        self._mixture_fit = None
        # Squared planar error of each untried gait's predicted landing, as it was before the
        # gait was learnt (acquisition.caution: how wrong the prior is for this robot).
        self._surprises = []
        # Those of the steps chosen on a self-model's table: the caution it is used with is
        # its own record's, not that of the priors that failed before it came.
        self._model_surprises = []

    def set_config(self, config) -> None:
        """Go on with another :class:`SELAConfig` (what is learnt stays)."""
        if isinstance(config, dict):
            config = SELAConfig.from_dict(config)
        if not isinstance(config, SELAConfig):
            raise TypeError(f'config must be a SELAConfig or a dict, got {type(config).__name__}')
        self.config = config

    def forget_learning(self) -> None:
        """Back to the intact map: every observation forgotten, also what restarts set aside
        (what was learnt about falls stays, as in :meth:`reset_learning`)."""
        self.reset_learning()
        self.set_aside_learning = []

    def set_aside(self, reason, keep_from=None) -> int:
        """Start learning afresh without losing what was learned: the observations before
        ``keep_from`` (all of them with None) are set aside with ``reason`` (kept in
        :meth:`state_dict` under ``set_aside``, at most :data:`SET_ASIDE_KEPT` episodes,
        and brought back by :meth:`recover`); those from ``keep_from`` on are learnt again.
        Returns how many observations were set aside."""
        idx, grs = self.observations
        standing = list(self._standing)
        cut = len(idx) if keep_from is None else max(0, min(int(keep_from), len(idx)))
        if cut:
            self.set_aside_learning.append({
                'reason': str(reason), 'indices': idx[:cut].tolist(),
                'generic_rewards': grs[:cut].tolist(), 'standing_starts': standing[:cut]})
            del self.set_aside_learning[:-SET_ASIDE_KEPT]
        self.reset_learning()
        for i, y, st in zip(idx[cut:], grs[cut:], standing[cut:]):
            self.tell(int(i), y, st)
        return cut

    def change_evidence(self, config=None) -> change_evidence.Evidence:
        """Whether the latest observations say the robot changed
        (:func:`~sela_ros.core.detection.change_evidence.change_evidence`, with this SELA's
        kernel)."""
        idx, grs = self.observations
        c = self.config
        return change_evidence.change_evidence(self._candidates, self._prior, idx, grs,
                                               c.gp_kernel_sigma, c.gp_kernel_variance,
                                               c.gp_noise, config)

    def recover(self) -> int:
        """Bring back the latest learning set aside (:meth:`set_aside`), before what was
        learned since; returns how many observations came back (0: none was set aside)."""
        if not self.set_aside_learning:
            return 0
        episode = self.set_aside_learning.pop()
        idx, grs = self.observations
        standing = list(self._standing)
        self.reset_learning()
        back = list(zip(episode['indices'], episode['generic_rewards'],
                        episode['standing_starts']))
        for i, y, st in back + list(zip(idx, grs, standing)):
            self.tell(int(i), y, bool(st))
        return len(back)

    def forget_falls(self) -> None:
        """Forget every observed fall: back to the prior fall rates."""
        c = self.config
        sigma = c.gp_kernel_sigma if c.fall_kernel_sigma is None else c.fall_kernel_sigma
        self._fall = fall_risk.FallRisk(self._candidates, self._prior_fall_rate, sigma=sigma,
                                        variance=c.gp_kernel_variance,
                                        noise=c.gp_noise, stability=self._stability)

    def set_goal(self, goal) -> None:
        goal = np.asarray(goal, dtype=float).reshape(-1)
        if goal.shape[0] < 2 or not np.all(np.isfinite(goal[:2])):
            raise ValueError(f'goal must be a finite (x, y), got {goal!r}')
        self.goal = goal[:2].copy()

    def _check_pose(self, pose):
        pose = np.asarray(pose, dtype=float).reshape(-1)
        if pose.shape != (self.motion.pose_dim,) or not np.all(np.isfinite(pose)):
            raise ValueError(f'pose must be {self.motion.pose_dim} finite numbers, got {pose}')
        return pose

    def goal_reached(self, pose) -> bool:
        if self.goal is None:
            return False
        pose = self._check_pose(pose)
        return bool(np.linalg.norm(pose[:2] - self.goal) < self.config.goal_eps)

    def select_prior(self) -> damage_priors.Selection:
        """The prior mean the next choice uses: the intact map, the damage prior that
        best explains the steps seen so far (:meth:`DamagePriors.select`) if it reproduced
        the robot's standing starts (the robot's own damage, foreseen) or no step started
        standing, else the mixture of the tables that fits the steps
        (:func:`~sela_ros.core.learning.prior_mixture.fit_mixture`); with
        ``priors.weights.sd`` none, the selected table or the intact map whatever it
        reproduced."""
        tables = self._tables()
        if tables is None or not self._gp.num_samples:
            return damage_priors.INTACT
        fall_idx, fallen = self._fall.observations
        idx, grs = self.observations
        selection = tables.select(self._prior, idx, grs, fall_idx, fallen,
                                  self.config.priors_max_misfit, self._standing,
                                  self.config.priors_max_misfit_reproduced)
        # With no step from a standing start there is nothing a table could reproduce: a
        # table that explains the steps (priors.max.misfit) is then used as it is.
        unjudged = selection.index is not None and not any(self._standing)
        scores = self._prior_scores
        if self.config.priors_weights_sd is None or selection.reproduced or unjudged \
                or scores['mixture'] <= scores['table']:
            return selection
        mixture = self._mixture(idx, grs, fall_idx, fallen)
        return damage_priors.Selection(None, MIXTURE, mixture.misfit, mixture=mixture)

    def _mixture(self, idx, grs, fall_idx, fallen):
        # The same steps are fitted twice, when a step is scored before it is learnt and
        # when the next gait is chosen: the fit is kept for the steps it was made on.
        key = (np.asarray(idx).tobytes(), np.asarray(grs).tobytes(),
               np.asarray(fall_idx).tobytes(), np.asarray(fallen).tobytes(),
               tuple(self._standing), self.config.priors_weights_sd)
        if self._mixture_fit is None or self._mixture_fit[0] != key:
            self._mixture_fit = (key, prior_mixture.fit_mixture(
                self._prior, self._tables().generic_reward, idx, grs, fall_idx, fallen,
                self._standing, weight_sd=self.config.priors_weights_sd))
        return self._mixture_fit[1]

    def _score_priors(self, index, observed, standing) -> None:
        """Score the one-table choice and the mixture on a step about to be learnt: the
        likelihood of what it did under each one's posterior mean, from the steps before it
        (a prequential comparison: each is judged on predicting gaits it has not seen; the
        mixture's K weights fit the steps seen better than one table can, so their fit
        alone would always prefer it). The mixture is used only while it predicts better:
        on a leg removed whose own table is left out, the other legs' tables predict the
        gaits no better than the intact map (docs/priors_combination.md)."""
        fall_idx, fallen = self._fall.observations
        if fall_idx.size and fall_idx[-1] == index and fallen[-1]:
            return  # the tumble's displacement tests neither
        idx, grs = self.observations
        k = self.motion.gr_dim
        tables = self._tables()
        selection = tables.select(self._prior, idx, grs, fall_idx, fallen,
                                  self.config.priors_max_misfit, self._standing,
                                  self.config.priors_max_misfit_reproduced)
        rows = np.append(idx, index)
        one = (self._prior if selection.index is None
               else tables.generic_reward[selection.index])[rows, :k]
        weights = self._mixture(idx, grs, fall_idx, fallen).weights
        base = self._prior[rows]
        mixed = base + np.tensordot(weights, tables.generic_reward[:, rows, :k] - base,
                                    axes=1)
        for key, prior in (('table', one), ('mixture', mixed)):
            predicted = self._gp.mean_at_with_prior(index, prior[:-1], prior[-1])
            self._prior_scores[key] += prior_mixture.step_log_likelihood(
                observed - predicted, standing)

    def _posterior(self, selection):
        """``(mu (k, M), var (M,), fall prior)`` under ``selection``: the fall prior is the
        arguments of :meth:`FallRisk.risk` that the selected damage prior gives (its falls,
        its support prior, and its chained runs if it reproduced the robot's standing
        starts: those of another damage mislead), ``()`` for the intact map. A second-tier
        table gives its falls alone once the robot has fallen on a gait it says stands: it
        is in use on the strength of a few standing starts, then on a damage it does not
        hold (a leg removed read as a leg shortened), and its support prior, weighed as
        :data:`~sela_ros.core.learning.fall_risk.TABLE_EVIDENCE` gaits, would go on telling
        the fall model that this robot rarely falls; the generic prior takes its place,
        moved by the robot's own steps (docs/learning_the_damage.md, "The fall model under
        a second-tier table"). The variance is on the configured kernel's scale (a share of
        ``gp.kernel.variance``) whatever signal variance was learnt (``gp.hyper.sd``): the
        choice reads it as such."""
        prior = self._effective_prior(selection)
        self._learn_hyper(prior)
        mu_t, _ = self._gp.query_columns()
        var = self._choice_variance()
        if selection.mixture is not None:
            # The mixture's falls set the fall model's prior as a table's do; no chained runs:
            # those of the damages mixed mislead on another robot (docs/notebook.md).
            rates = selection.mixture.fall_rates(self._tables().fallen)
            return (self._gp.mean_columns_with_prior(prior), var,
                    (rates, self._fall.table_support(rates), None))
        if selection.index is None:
            return (mu_t if prior is None else self._gp.mean_columns_with_prior(prior)), var, ()
        tables = self._tables()
        fallen = tables.fallen[selection.index]
        support = None
        if not tables.second_tier[selection.index] or not self._fell_where_stands(fallen):
            if selection.index not in self._support:
                self._support[selection.index] = self._fall.table_support(fallen)
            support = self._support[selection.index]
        return (self._gp.mean_columns_with_prior(prior), var,
                (fallen.astype(float), support,
                 tables.chained(selection.index) if selection.reproduced else None))

    def _fell_where_stands(self, fallen) -> bool:
        """Has the robot fallen on a gait that a table's ``fallen`` (M,) says stands?"""
        fall_idx, fell = self._fall.observations
        return bool((fell & ~fallen[fall_idx]).any())

    def _choice_variance(self):
        """``(M,)`` the posterior variance the choice reads, on the configured kernel's
        scale: the GP's, times the configured signal variance over the GP's (1 unless
        ``gp.hyper.sd`` changed it), or the configured kernel's GP's
        (:data:`HYPER_VARIANCE_LEARNT` False)."""
        if self._gp_configured is not None:
            return self._gp_configured.query_columns()[1]
        var = self._gp.query_columns()[1]
        scale = self.config.gp_kernel_variance / self._gp.variance
        return var if scale == 1.0 else var * scale

    def _learn_hyper(self, prior) -> None:
        """With ``gp.hyper.sd``, the kernel length and signal variance that the residuals of
        the steps under the prior mean in use (``prior``, None: the intact map) make most
        probable (:func:`~sela_ros.core.learning.hyper.choose`; the GP is refactorised only
        when they change)."""
        c = self.config
        if c.gp_hyper_sd is None or not self._gp.num_samples:
            return
        idx, grs = self.observations
        fall_idx, fallen = self._fall.observations
        # A tumble's displacement says nothing of how smooth this robot's gaits are.
        keep = ~np.isin(idx, fall_idx[fallen]) if fallen.any() else np.ones(len(idx), bool)
        if not keep.any():
            return
        base = self._prior if prior is None else prior
        residuals = grs[keep] - base[idx[keep], :grs.shape[1]]
        sigma, variance = hyper.choose(self._gp.sq_distances[np.ix_(keep, keep)], residuals,
                                       c.gp_noise, c.gp_kernel_sigma, c.gp_kernel_variance,
                                       c.gp_hyper_sd, current=self.hyper)
        self._gp.set_hyper(sigma, variance)
        if not HYPER_VARIANCE_LEARNT and self._gp_configured is None \
                and self.hyper != (c.gp_kernel_sigma, c.gp_kernel_variance):
            self._gp_configured = gp.CandidateSetGP(
                self._candidates, self._prior, sigma=c.gp_kernel_sigma,
                variance=c.gp_kernel_variance, noise=c.gp_noise)
            self._gp_configured.fit(idx, grs)

    @property
    def hyper(self):
        """``(kernel length, signal variance)`` of the GP in use."""
        return self._gp.sigma, self._gp.variance

    def _effective_prior(self, selection):
        """The ``(M, k)`` prior mean the GPs' residuals are taken from: ``selection``'s
        (:meth:`_prior_mean`), mapped by the affine map learnt from the steps
        (``gp.mean.affine``, :mod:`~sela_ros.core.learning.affine_mean`); None: the intact
        map as it is (the GPs' own)."""
        table = self._prior_mean(selection)
        base = self._prior if table is None else table
        weights = self._affine_weights(base, selection)
        return table if weights is None else affine_mean.apply_affine(weights, base,
                                                                      self._candidates)

    def _affine_weights(self, base, selection):
        """The affine map of the prior mean ``base`` in use (:meth:`_fit_affine`), or None:
        off, it has not predicted the steps better than the prior mean as it is, or
        ``selection`` is a table that reproduced the robot's standing starts (its own damage,
        foreseen: what is left of the table's error is the GPs' to learn, gait by gait)."""
        if self._affine_score <= AFFINE_MIN_SCORE or selection.reproduced:
            return None
        return self._fit_affine(base)

    def _fit_affine(self, base):
        """The affine map (:func:`~sela_ros.core.learning.affine_mean.fit_affine`) of the
        prior mean ``base`` learnt from the steps that stayed up, or None (off, or no such
        step)."""
        sd = self.config.gp_mean_affine
        if sd is None or not self._gp.num_samples:
            return None
        idx, grs = self.observations
        fall_idx, fallen = self._fall.observations
        # A step that ended on the ground says nothing of how this robot walks.
        keep = ~np.isin(idx, fall_idx[fallen]) if fallen.any() else np.ones(len(idx), bool)
        if not keep.any():
            return None
        return affine_mean.fit_affine(base[idx[keep]], grs[keep], sd,
                                      self._candidates[idx[keep]],
                                      self.config.gp_mean_descriptor)

    def _prior_mean(self, selection):
        """The ``(M, k)`` prior mean ``selection`` stands for: the tables mixed, one table,
        or None for the intact map (the GPs' own)."""
        if selection.mixture is not None:
            return selection.mixture.mean(self._prior, self._tables().generic_reward)
        if selection.index is None:
            return None
        return self._tables().generic_reward[selection.index][:, :self.motion.gr_dim]

    def predict(self):
        """Posterior over the archive: ``(mu (M, k), sigma (M,))`` (under the prior in use)."""
        mu_t, var, _ = self._posterior(self.select_prior())
        return mu_t.T, np.sqrt(var)

    def ask(self, pose, waypoint=None, next_waypoint_xy=None, map_trusted=False) -> Decision:
        """Choose the next behaviour from ``pose`` (raises PlanningError if no path).

        ``waypoint``: the reward selection layer's answer when it runs elsewhere (the
        planner node); None: plan to the goal here and take ``planner.lookahead`` along it.
        ``next_waypoint_xy``: with ``planner.horizon`` 2 and a given ``waypoint``, the
        waypoint of the step after (None: the last step before the goal, one step only).
        ``map_trusted``: no damage is known yet (the adapter before its detector's verdict):
        choose on the map alone. Otherwise the first step of an adaptation with damage priors,
        before any step has shown which damage the robot has, is hedged over the intact map
        and every table (:meth:`_hedged_choice`).
        """
        pose = self._check_pose(pose)
        second = None
        waypoint_given = waypoint is not None
        if waypoint is not None:
            waypoint = np.asarray(waypoint, dtype=float).reshape(-1)[:2]
            path = np.array([pose[:2], waypoint])
            if next_waypoint_xy is not None:
                second = np.asarray(next_waypoint_xy, dtype=float).reshape(-1)[:2]
        else:
            if self.goal is None:
                raise RuntimeError('no goal: call set_goal() before ask()')
            path = np.asarray(self.planner(pose[:2], self.goal), dtype=float)
            waypoint = next_waypoint(path, pose[:2], self.config.planner_lookahead)
            if self.config.planner_horizon > 1:
                second = next_waypoint(path, pose[:2], 2 * self.config.planner_lookahead)
        tables = self._tables()
        if tables is not None and len(tables) and not self._gp.num_samples \
                and not map_trusted:
            return self._hedged_choice(pose, waypoint, path)
        selection = self.select_prior()
        mu_t, var, fall_prior = self._posterior(selection)
        x, y = self.motion.predict_xy_columns(pose, mu_t)
        landing_var = self._landing_variance(var, selection)
        sq_distance = (x - waypoint[0]) ** 2 + (y - waypoint[1]) ** 2
        track = self._track(pose, waypoint, path, waypoint_given)
        if track is not None:
            reward = acquisition.progress_reward(track, x, y, waypoint,
                                                 self.config.acquisition_progress, landing_var)
        else:
            reward = -(np.sqrt(sq_distance) if landing_var is None
                       else acquisition.expected_distance(sq_distance, landing_var))
        risk = self._fall.risk(*fall_prior)
        fall_aware = bool(self._fall.falls or self._prior_fall_rate is not None
                          or self._stability is not None or fall_prior)
        chance = None
        if track is None and landing_var is not None \
                and self.config.acquisition_reach is not None:
            chance = self._reach_chance(sq_distance, landing_var,
                                        risk if fall_aware else None)
            if chance is not None:
                reward = acquisition.reach_reward(chance, -reward,
                                                  self.config.acquisition_reach)
        nearer = None
        if landing_var is not None and self.goal is not None and np.linalg.norm(
                waypoint - self.goal) <= self.config.goal_eps:
            # The step to the goal: a gait tried that barely moves would always seem surer
            # than one that could land on the goal; only gaits predicted to bring the robot
            # a goal.eps nearer are in the running, if any is allowed.
            nearer = np.sqrt(sq_distance) <= np.linalg.norm(pose[:2] - waypoint) \
                - self.config.goal_eps
        sigma = np.sqrt(var)
        scores = acquisition.ucb_scores(reward, sigma, self.config.acquisition_ucb_alpha)
        if fall_aware:
            if self.config.fall_risk_cost:
                scores = scores - self.config.fall_risk_cost * risk
            scores = fall_risk.safe_choice(scores, risk, self.config.fall_risk_threshold)
        if nearer is not None and (nearer & np.isfinite(scores)).any():
            scores = np.where(nearer, scores, -np.inf)
        scores = self._within_simulated(selection, scores)
        index = int(np.argmax(scores))
        if self.config.planner_horizon > 1 and second is not None \
                and np.linalg.norm(second - waypoint) > 1e-6:
            index = self._two_step_choice(pose, mu_t, scores, risk if fall_aware else None,
                                          second, index, landing_var, track, waypoint,
                                          chance)
        gr = mu_t[:, index].copy()
        return Decision(index=index, waypoint=waypoint, predicted_gr=gr,
                        predicted_pose=self.motion.predict(pose, gr),
                        reward=float(reward[index]), sigma=float(sigma[index]), path=path,
                        fall_risk=float(risk[index]),
                        candidates=top_candidates(index, x, y, sigma, scores),
                        prior=selection.name)

    def _within_simulated(self, selection, scores):
        """``scores`` with the gaits that ``selection``'s table inferred rather than
        simulated (the damage library's tables: :meth:`DamagePriors.inferred`) and the robot
        has not tried ruled out, if any gait allowed is left. The inferred outcomes of a
        damage that tips the robot are often wrong where the simulated ones hold
        (docs/learning_the_damage.md, "Two legs lost: standing starts by share, tables
        trusted where they were simulated")."""
        if selection.index is None:
            return scores
        inferred = self._tables().inferred(selection.index)
        if inferred is None:
            return scores
        allowed = ~inferred
        allowed[self.observations[0]] = True
        if not (allowed & np.isfinite(scores)).any():
            return scores
        return np.where(allowed, scores, -np.inf)

    def _hedged_choice(self, pose, waypoint, path) -> Decision:
        """The first step on a damage not known yet: the gait whose landing is nearest the
        waypoint on average over the intact map and every damage prior, its risk the fall
        model's (the intact map's prior) or the share of those that see it fall, whichever is
        higher, weighed and capped as in every step; one step ahead.

        Nothing tells the damages apart before the robot has moved, so the step the intact
        map alone picks is often one the damaged robots cannot do (measured: docs/notebook.md,
        "The first step and the fall model on a known damage")."""
        c = self.config
        k = self.motion.gr_dim
        priors = self._tables()
        tables = [self._prior] + [g[:, :k] for g in priors.generic_reward]
        distance, x, y = (np.zeros(self.num_candidates) for _ in range(3))
        for table in tables:
            tx, ty = self.motion.predict_xy_columns(pose, table.T)
            distance += np.hypot(tx - waypoint[0], ty - waypoint[1])
            x += tx
            y += ty
        distance, x, y = distance / len(tables), x / len(tables), y / len(tables)
        falls = priors.fallen.sum(axis=0) / len(tables)
        risk = np.maximum(self._fall.risk(), falls)
        scores = fall_risk.safe_choice(-distance - c.fall_risk_cost * risk, risk,
                                       c.fall_risk_threshold)
        index = int(np.argmax(scores))
        gr = np.mean([table[index] for table in tables], axis=0)
        _, var = self._gp.query_columns()
        sigma = np.sqrt(var)
        return Decision(index=index, waypoint=waypoint, predicted_gr=gr,
                        predicted_pose=self.motion.predict(pose, gr),
                        reward=float(-distance[index]), sigma=float(sigma[index]), path=path,
                        fall_risk=float(risk[index]),
                        candidates=top_candidates(index, x, y, sigma, scores),
                        prior=HEDGED)

    def _track(self, pose, waypoint, path, waypoint_given):
        """The path the progress of a landing is measured along (``acquisition.progress``):
        the planned one, or with only the waypoint given, from the robot through it to the
        goal; None: the progress is not used."""
        if self.config.acquisition_progress is None:
            return None
        if not waypoint_given:
            return path
        points = [pose[:2], waypoint]
        if self.goal is not None and np.linalg.norm(self.goal - waypoint) > 1e-6:
            points.append(self.goal)
        return np.array(points)

    def _reach_chance(self, sq_distance, landing_var, risk):
        """Each gait's probability of landing within ``acquisition.reach`` of the waypoint
        (``sq_distance`` from it, ``landing_var`` per axis), or None where no gait allowed
        (``risk`` at most ``fall.risk.threshold``; None: every gait) has
        :data:`~acquisition.REACH_MIN_CHANCE` of it: the expected distance then chooses."""
        chance = acquisition.reach_probability(sq_distance, landing_var,
                                               self.config.acquisition_reach)
        allowed = chance if risk is None else chance[risk <= self.config.fall_risk_threshold]
        if not allowed.size or allowed.max() < acquisition.REACH_MIN_CHANCE:
            return None
        return chance

    def _two_step_choice(self, pose, mu_t, scores, risk, second, index, landing_var=None,
                         track=None, waypoint=None, chance=None):
        """Among the :data:`TWO_STEP_CANDIDATES` best gaits by ``scores``, the one from whose
        predicted end pose the best next gait (risk weighed as in the first step) lands
        nearest ``second`` (with ``landing_var``, the caution's: in expectation, both
        landings uncertain), or with ``track`` (``acquisition.progress``), furthest along it
        from ``waypoint`` on; with ``chance`` (``acquisition.reach``: each gait's probability
        of landing within reach of the first waypoint), the one most likely to land within
        reach of both, falls counted as failures, if any second step has a real chance;
        ``index`` if no gait is allowed."""
        finite = np.flatnonzero(np.isfinite(scores))
        if not finite.size:
            return index
        top = finite[np.argsort(-scores[finite], kind='stable')[:TWO_STEP_CANDIDATES]]
        c = self.config
        if risk is None:
            penalty = first = 0.0
        else:
            penalty = np.where(risk <= c.fall_risk_threshold, c.fall_risk_cost * risk, np.inf)
            first = c.fall_risk_cost * risk
        # Every candidate's end pose at once: (K, M) distances of the next gaits' landings.
        ends = self.motion.predict(pose, mu_t[:, top].T).reshape(len(top), -1)
        if track is not None:
            cost = -self._two_step_progress(ends, mu_t, track, waypoint, second, top,
                                            landing_var)
        else:
            cost = self.motion.landing_sq_distances(ends, mu_t, second)  # (K, M), in place:
            np.maximum(cost, 0.0, out=cost)
            if landing_var is not None:  # the expected distances: both landings' spread
                cost += 2.0 * landing_var[None, :]
                cost += 2.0 * landing_var[top][:, None]
            if chance is not None:
                both = self._reach_both(cost, landing_var, top, chance, risk)
                if both is not None:
                    return int(top[int(np.argmax(both))])
            np.sqrt(cost, out=cost)                                   # the distances, then
        if risk is not None:                                          # + the risk penalty
            cost += penalty
        value = -cost.min(axis=1)
        if risk is not None:
            value = value - first[top]
        return int(top[int(np.argmax(value))]) if np.isfinite(value).any() else index

    def _reach_both(self, cost, landing_var, top, chance, risk):
        """(K,) value (m) of the first gaits ``top``: the reach times the probability that
        the first lands within reach of its waypoint (``chance``) and the best next gait
        within reach of the second, less both gaits' fall cost (as in one step);
        ``cost``: (K, M) the expected squared distances of the second landings (both spreads
        in). None where no second gait allowed has :data:`~acquisition.REACH_MIN_CHANCE`."""
        c = self.config
        reach = c.acquisition_reach
        # Only the second gaits expected nearest matter: a gait far out of reach has no
        # chance, and the chance of the (K, M) landings would cost more than the rest.
        near = min(REACH_SECOND_CANDIDATES, cost.shape[1])
        cols = np.argpartition(cost, near - 1, axis=1)[:, :near]
        rows = np.arange(len(top))[:, None]
        var = landing_var[top][:, None] + landing_var[cols]
        second = acquisition.reach_probability(cost[rows, cols] - 2.0 * var, var, reach)
        fall = 0.0 if risk is None else c.fall_risk_cost * risk[cols]
        if risk is not None:
            second = np.where(risk[cols] <= c.fall_risk_threshold, second, -np.inf)
        if not second.max() >= acquisition.REACH_MIN_CHANCE:
            return None
        best = np.argmax(reach * second - fall, axis=1)
        both = reach * chance[top] * second[rows[:, 0], best]
        if risk is not None:
            both -= c.fall_risk_cost * (risk[top] + risk[cols[rows[:, 0], best]])
        return both

    def _two_step_progress(self, ends, mu_t, track, waypoint, second, top, landing_var):
        """(K, M) progress rewards (:func:`~acquisition.progress_reward`) beyond ``second``
        of every gait's landing from each of the K end poses ``ends`` of the gaits ``top``,
        along ``track`` from ``waypoint`` (the first step's) on."""
        theta = ends[:, 2] if ends.shape[1] > 2 else np.zeros(len(ends))
        # Only the track from the first waypoint on, to twice as far beyond the second: the
        # second landings lie there, and a few segments keep the (K, M) products few.
        track = acquisition.path_from(track, waypoint,
                                      3.0 * np.linalg.norm(np.asarray(second) - waypoint))
        var = None
        if landing_var is not None:
            var = landing_var[None, :] + landing_var[top][:, None]
        return acquisition.progress_reward_from(track, ends, np.cos(theta), np.sin(theta),
                                                mu_t, second, self.config.acquisition_progress,
                                                var)

    def tell(self, index: int, observed_gr, standing_start: bool = False) -> None:
        """Learn that behaviour ``index`` produced the generic reward ``observed_gr``;
        ``standing_start``: the step started with the robot standing (the first of a run, or
        after it was put back on its feet), as the damage priors' tables ran every gait."""
        observed = np.asarray(observed_gr, dtype=float).reshape(-1)
        valid = observed.shape == (self.motion.gr_dim,) and np.all(np.isfinite(observed)) \
            and isinstance(index, (int, np.integer)) and 0 <= index < self.num_candidates
        # (The first step of an adaptation with damage priors is hedged over the first tier:
        # no one prior predicted it.)
        tables = self._tables()
        hedged = tables is not None and len(tables) and not self._gp.num_samples
        if valid and not hedged and self.config.acquisition_caution is not None:
            self._note_surprise(int(index), observed)
        if tables is not None and len(tables) and self._gp.num_samples \
                and self.config.priors_weights_sd is not None and valid:
            self._score_priors(int(index), observed, bool(standing_start))
        if valid and not hedged and self.config.gp_mean_affine is not None:
            self._score_affine(int(index), observed, bool(standing_start))
        self._gp.add_sample(index, observed_gr)
        if self._gp_configured is not None:
            self._gp_configured.add_sample(index, observed_gr)
        self._standing.append(bool(standing_start))

    def _note_surprise(self, index, observed) -> None:
        """Keep how far an untried gait landed from its prediction under the prior in use
        (before it is learnt: a prequential error)."""
        mu_t, _ = self._gp.query_columns()
        if self._choice_variance()[index] <= acquisition.UNTRIED_VARIANCE:
            return
        selection = self.select_prior()
        table = self._prior_mean(selection)
        base = self._prior if table is None else table
        weights = self._affine_weights(base, selection)
        if table is None and weights is None:
            predicted = mu_t[:, index]
        else:
            idx, _ = self.observations
            gaits = np.append(idx, index)
            rows = base[gaits]
            if weights is not None:
                rows = affine_mean.apply_affine(weights, rows, self._candidates[gaits])
            predicted = self._gp.mean_at_with_prior(index, rows[:-1], rows[-1])
        self._surprises.append(float(np.sum((observed[:2] - predicted[:2]) ** 2)))
        if _self_model_table(selection):
            self._model_surprises.append(self._surprises[-1])

    def _score_affine(self, index, observed, standing) -> None:
        """Add how much better the affine map fitted to the steps before predicted this one
        than the prior mean as it is (log-likelihoods of the damage priors' error model)."""
        table = self._prior_mean(self.select_prior())
        base = self._prior if table is None else table
        weights = self._fit_affine(base)
        if weights is None:
            return
        idx, _ = self.observations
        gaits = np.append(idx, index)
        rows = base[gaits]
        mapped = affine_mean.apply_affine(weights, rows, self._candidates[gaits])
        plain = self._gp.mean_at_with_prior(index, rows[:-1], rows[-1])
        fitted = self._gp.mean_at_with_prior(index, mapped[:-1], mapped[-1])
        self._affine_score += prior_mixture.step_log_likelihood(observed - fitted, standing) \
            - prior_mixture.step_log_likelihood(observed - plain, standing)

    def _landing_variance(self, var, selection=None):
        """Per gait, the variance of its landing if caution is on
        (``acquisition.caution``, and the untried gaits' learnt error at least that), else
        None. Under a self-model's table (``selection``) the error is learnt from the steps
        chosen on it alone: it is a model of the damage the feet showed, made after the
        priors before it had disappointed (docs/learning_the_damage.md, "The self-model's
        table refined and judged on its own record")."""
        caution = self.config.acquisition_caution
        if caution is None:
            return None
        error = acquisition.learnt_error(self._model_surprises if _self_model_table(selection)
                                         else self._surprises)
        return acquisition.landing_variance(var, error) if error >= caution else None

    def tell_fall(self, index: int, fallen: bool) -> None:
        """Learn whether behaviour ``index`` tipped the robot over. Every step tells it,
        also while the map is still trusted and generic rewards are not learnt."""
        self._fall.tell(index, fallen)

    @property
    def fall_observations(self) -> int:
        """How many steps told whether they fell (:meth:`tell_fall`)."""
        return self._fall.num_observations

    @property
    def observations(self):
        """``(indices (N,), generic rewards (N, k))`` told so far."""
        return np.array(self._gp.indices, dtype=int), self._gp.observed

    def state_dict(self) -> dict:
        """What was learned, as JSON-able plain lists."""
        idx, grs = self.observations
        fall_idx, fallen = self._fall.observations
        return {'num_candidates': self.num_candidates, 'gr_dim': self.motion.gr_dim,
                'config': self.config.to_dict(),
                'goal': None if self.goal is None else self.goal.tolist(),
                'indices': idx.tolist(), 'generic_rewards': grs.tolist(),
                'standing_starts': list(self._standing),
                'prior_scores': dict(self._prior_scores),
                'surprises': list(self._surprises),
                'hyper': list(self.hyper),
                'fall_indices': fall_idx.tolist(), 'fallen': fallen.tolist(),
                'set_aside': [dict(e) for e in self.set_aside_learning]}

    def keep_latest(self, count: int) -> int:
        """Keep the latest ``count`` observations of generic rewards and of falls, and
        forget the older ones (a lifelong robot's learning stays bounded; what the recent
        steps say of its body is what matters). What the steps scored stays. Returns how
        many observations were forgotten."""
        count = int(count)
        idx, grs = self.observations
        fall_idx, fallen = self._fall.observations
        drop, drop_falls = max(0, len(idx) - count), max(0, len(fall_idx) - count)
        if drop:
            scores, surprises = dict(self._prior_scores), self._surprises[-count:]
            model_surprises = self._model_surprises[-count:]
            standing, kernel = self._standing[drop:], self.hyper
            self.reset_learning()
            self._gp.set_hyper(*kernel)
            self._gp.fit(idx[drop:], grs[drop:])
            self._standing = standing
            self._prior_scores, self._surprises = scores, surprises
            self._model_surprises = model_surprises
        if drop_falls:
            self.forget_falls()
            self._fall.tell_many(fall_idx[drop_falls:], fallen[drop_falls:])
        return max(drop, drop_falls)

    def load_state_dict(self, state: dict, keep: int | None = None) -> None:
        """Restore what :meth:`state_dict` saved (same archive); replays the observations
        (only the latest ``keep`` of them, None: all)."""
        if int(state.get('num_candidates', -1)) != self.num_candidates:
            raise ValueError(f'state is for {state.get("num_candidates")} candidates, this '
                             f'SELA has {self.num_candidates}')
        if 'config' in state:
            self.config = SELAConfig.from_dict(state['config'])
        self.goal = None
        if state.get('goal') is not None:
            self.set_goal(state['goal'])
        indices = list(state.get('indices', []))
        grs = np.asarray(state.get('generic_rewards', []), dtype=float).reshape(
            len(indices), self.motion.gr_dim)
        # Files written before standing starts were recorded: none.
        standing = [bool(f) for f in state.get('standing_starts', [False] * len(indices))]
        if len(standing) != len(indices):
            raise ValueError(f'state has {len(indices)} indices but {len(standing)} '
                             'standing_starts flags')
        fall_indices = [int(i) for i in state.get('fall_indices', [])]
        fallen = [bool(f) for f in state.get('fallen', [])]
        if len(fall_indices) != len(fallen):
            raise ValueError(f'state has {len(fall_indices)} fall_indices but {len(fallen)} '
                             'fallen flags')
        set_aside = []
        for episode in state.get('set_aside', []):
            n = len(episode['indices'])
            set_aside.append({
                'reason': str(episode.get('reason', '')),
                'indices': [int(i) for i in episode['indices']],
                'generic_rewards': np.asarray(episode['generic_rewards'], dtype=float).reshape(
                    n, self.motion.gr_dim).tolist(),
                'standing_starts': [bool(f) for f in episode.get('standing_starts',
                                                                 [False] * n)]})
        if keep is not None:
            first, first_fall = max(0, len(indices) - keep), max(0, len(fall_indices) - keep)
            indices, grs, standing = indices[first:], grs[first:], standing[first:]
            fall_indices, fallen = fall_indices[first_fall:], fallen[first_fall:]
            for episode in set_aside:
                for key in ('indices', 'generic_rewards', 'standing_starts'):
                    episode[key] = episode[key][-keep:]
        self.reset_learning()
        self.forget_falls()
        self.set_aside_learning = set_aside[-SET_ASIDE_KEPT:]
        kernel = state.get('hyper')
        if self.config.gp_hyper_sd is not None and isinstance(kernel, list) \
                and len(kernel) == 2 and all(_positive(v) for v in kernel):
            # The kernel the GP had (gp.hyper.sd): the next choice goes on from it.
            self._gp.set_hyper(*kernel)
        scores = state.get('prior_scores')
        scores = ({k: float(v) for k, v in scores.items()} if isinstance(scores, dict)
                  and set(scores) == set(self._prior_scores) else None)
        surprises = state.get('surprises')
        surprises = ([float(v) for v in surprises] if isinstance(surprises, list) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
            and v >= 0 for v in surprises) else None)
        if scores is not None and surprises is not None:
            # What the steps scored as they came is saved: the replay only learns them, at
            # once (scoring each again would take seconds per hundred steps, and give the
            # saved values back less exactly, without the falls between the steps).
            self._gp.fit(indices, grs)
            self._standing = list(standing)
        else:
            for i, y, st in zip(indices, grs, standing):
                self.tell(int(i), y, st)
        self._fall.tell_many(fall_indices, fallen)
        if scores is not None:
            self._prior_scores = scores
        if surprises is not None:
            self._surprises = surprises if keep is None else surprises[-keep:]


def _self_model_table(selection) -> bool:
    """Is ``selection`` (a :class:`~sela_ros.core.learning.damage_priors.Selection`, or
    None) one table, the self-model's?"""
    return selection is not None and selection.index is not None \
        and selection.mixture is None and str(selection.name).startswith(SELF_MODEL)


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and bool(np.isfinite(value)) and value > 0
