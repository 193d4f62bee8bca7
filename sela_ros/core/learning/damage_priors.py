"""Damage priors: the archive's gaits evaluated in simulation on damages foreseen offline.

SELA's prior is the intact robot's map. A damaged robot moves about half as far as that map
says (``scripts/prior_error.py``), so every gait it has not tried looks better than the ones
it has, and it explores gaits one by one. When a damage can be foreseen (a leg lost), the
same gaits can be evaluated offline on a simulated robot with that damage, and each such
table is a better prior for that robot than the intact map. This is the idea of prior
selection (Pautrat, Chatzilygeroudis and Mouret, "Bayesian optimization with automatic prior
selection for data-efficient direct policy search", ICRA 2018), on SELA's generic rewards.

:meth:`DamagePriors.select` picks, after every step, the prior that best explains what the
robot has done so far: the intact map or one of the tables, by the likelihood of the
observed generic rewards (Gaussian errors of :data:`RESIDUAL_SCALE`, what a gait chained
from the last one differs from the same gait from a standing start, robust to a share
:data:`OUTLIER_FRACTION` of steps off by :data:`OUTLIER_SCALE` times that) and of the
observed falls. A table is used only while it explains the steps well in absolute terms too (median
squared error below ``max_misfit``, in units of :data:`RESIDUAL_SCALE`; of an even number
of steps the lower of the two middle ones, so that one surprise in the first two steps does
not set the right table aside; up to ``max_misfit_reproduced`` for a table that reproduced
the steps the robot made from a standing start, which is what the table ran: at least
:data:`REPRODUCED_SHARE` of them): a damage nobody
foresaw is best explained by the nearest table, which can still be wrong about most gaits,
and then the intact map with SELA's usual learning does better (docs/notebook.md, "Damage
priors"). The GPs keep their observations whatever prior is chosen; only their prior mean
changes, so switching is free and nothing learnt is lost.

ROS-free, and no simulator: ``make priors`` (``scripts/build_priors.py``) builds the tables.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sela_ros.core.storage import NpzRefused, atomic_write, check_npz_size
from sela_ros.core.validation import ImplausibleOutcome, check_generic_rewards

#: Scale of a table's prediction error for a gait chained from the last one (x, y in metres,
#: yaw in radians): the measured error of chaining against a standing start is 0.07 m and
#: 0.19 rad rms (docs/notebook.md), rounded up.
RESIDUAL_SCALE = np.array([0.1, 0.1, 0.25])
#: Probability that a gait falls when chained, if the table says it falls from a standing
#: start, and if the table says it stays up.
P_FALL_IF_FALLS = 0.7
P_FALL_IF_STANDS = 0.05
#: The share of steps a table may get badly wrong (a gait chained from an odd posture), and
#: how much wider their errors are: the likelihood is robust to them.
OUTLIER_FRACTION = 0.1
OUTLIER_SCALE = 5.0
#: Median squared error per step (units of RESIDUAL_SCALE) above which a table is not used
#: (measured against 0.8, 1.0 and no cap: docs/notebook.md).
DEFAULT_MAX_MISFIT = 0.6
#: A step from a standing start (the first of a run, or after the robot was put back on its
#: feet) is the experiment the table ran: the right table repeats it up to the position
#: noise (squared error 0.02 per output). Its error counts as this many times smaller.
STANDING_PRECISION = 3.0
#: A table whose squared error per output is under this on a standing-start step
#: reproduced it; wrong tables rarely do (docs/notebook.md).
REPRODUCED = 0.1
#: The share of the standing-start steps seen that a table must have reproduced to have
#: reproduced the robot's standing starts. A damage that tips the robot (both front legs
#: lost) makes even a standing start vary: its own table missed 3 of 8 by 0.2-0.5 m
#: (docs/learning_the_damage.md, "Two legs lost: standing starts by share, tables trusted
#: where they were simulated").
REPRODUCED_SHARE = 1.0 / 3.0
#: The cap on the misfit of a table that reproduced the standing-start steps: its chained
#: steps may then be off by more (a gait chained from an odd posture) before it is set aside.
DEFAULT_MAX_MISFIT_REPRODUCED = 2.0
#: Two tables are near duplicates when they differ by less than this, rms over the gaits
#: that stand in both, in units of RESIDUAL_SCALE (docs/damage_library.md).
NEAR_DUPLICATE = 1.0
FORMAT_VERSION = 1


class DamagePriorError(ValueError):
    """A damage-priors file that cannot be used (missing, corrupt, another archive's)."""


def params_checksum(params) -> str:
    """SHA-256 of an archive's gait parameters (float64, C order): what ties tables to it."""
    data = np.ascontiguousarray(np.asarray(params, dtype=np.float64))
    return hashlib.sha256(data.tobytes()).hexdigest()


@dataclass(frozen=True)
class Selection:
    """Which prior :meth:`DamagePriors.select` chose: ``index`` into the tables (None: the
    archive's own, the intact map), its ``name``, its ``misfit``, and whether it
    ``reproduced`` the steps made from a standing start (:data:`REPRODUCED_SHARE` of them:
    the robot's own damage, then; its chained runs hold for this robot). ``mixture``: a
    :class:`~sela_ros.core.learning.prior_mixture.Mixture` of the tables instead of one (``index``
    None), or None."""

    index: int | None
    name: str
    misfit: float
    reproduced: bool = False
    mixture: object = None


INTACT = Selection(None, 'intact', 0.0)


@dataclass(frozen=True)
class DamagePriors:
    """Tables of every archive gait's outcome on foreseen damages.

    Attributes:
        names: ``(K,)`` damage specs (``remove:front_left``, ...).
        generic_reward: ``(K, M, k)`` each gait's generic reward from a standing start.
        fallen: ``(K, M)`` whether it tipped the robot over.
        archive_checksum: :func:`params_checksum` of the archive the tables are for.
        chained_runs, chained_falls: ``(K, M)`` how often each gait was run right after
            another one (the fast gaits the fall model fears: ``make priors``) and how often
            it fell then; None: none was.
        reproduce_only: ``(K,)`` the second tier: tables used only once one of them has
            reproduced the robot's standing starts (:meth:`first_tier`; the damage
            library's conditions), after every first-tier table; None: none is.
        simulated: ``(K, M)`` which gaits each table simulated; the others were inferred
            from them (the damage library's tables) and are not chosen while the table is
            the prior (:meth:`inferred`); None: every gait of every table was simulated.
    """

    names: tuple
    generic_reward: np.ndarray
    fallen: np.ndarray
    archive_checksum: str
    chained_runs: np.ndarray | None = None
    chained_falls: np.ndarray | None = None
    reproduce_only: np.ndarray | None = None
    simulated: np.ndarray | None = None

    def __post_init__(self):
        gr, fallen = np.asarray(self.generic_reward), np.asarray(self.fallen)
        k = len(self.names)
        if gr.ndim != 3 or gr.shape[0] != k or fallen.shape != gr.shape[:2]:
            raise DamagePriorError(f'damage priors: {k} names, generic_reward {gr.shape} and '
                                   f'fallen {fallen.shape} do not match')
        runs = np.zeros(fallen.shape, int) if self.chained_runs is None \
            else np.asarray(self.chained_runs)
        falls = np.zeros(fallen.shape, int) if self.chained_falls is None \
            else np.asarray(self.chained_falls)
        if runs.shape != fallen.shape or falls.shape != fallen.shape or \
                np.any(runs < 0) or np.any(falls < 0) or np.any(falls > runs):
            raise DamagePriorError(f'damage priors: chained runs {runs.shape} and falls '
                                   f'{falls.shape} must be counts of shape {fallen.shape}, '
                                   'no more falls than runs')
        # Per table, the gaits run chained with their runs and falls (FallRisk.risk).
        object.__setattr__(self, '_chained', [
            (np.flatnonzero(r), r[r > 0].astype(float), f[r > 0].astype(float))
            for r, f in zip(runs, falls)])
        try:
            check_generic_rewards(gr, what='damage priors: generic_reward')
        except ImplausibleOutcome as exc:
            raise DamagePriorError(str(exc)) from None
        if len(set(self.names)) != k:
            raise DamagePriorError(f'damage priors: names repeat: {list(self.names)}')
        second = np.zeros(k, bool) if self.reproduce_only is None \
            else np.asarray(self.reproduce_only)
        if second.shape != (k,) or second.dtype != bool:
            raise DamagePriorError(f'damage priors: reproduce_only must be {k} flags, got '
                                   f'{second.shape} {second.dtype}')
        # The first tier is a prefix: a table's index is the same in it and in the whole.
        if np.any(np.diff(second.astype(int)) < 0):
            raise DamagePriorError('damage priors: the reproduce-only tables must come after '
                                   f'the others: {list(self.names)}')
        object.__setattr__(self, '_second', second)
        object.__setattr__(self, '_first_tier', None)
        if self.simulated is not None:
            simulated = np.asarray(self.simulated)
            if simulated.shape != fallen.shape or simulated.dtype != bool:
                raise DamagePriorError(f'damage priors: simulated must be {fallen.shape} '
                                       f'flags, got {simulated.shape} {simulated.dtype}')
            empty = [n for n, row in zip(self.names, simulated) if not row.any()]
            if empty:
                raise DamagePriorError(f'damage priors: tables that simulated no gait: {empty}')
        # Per table, its inferred gaits (None: it simulated every one).
        object.__setattr__(self, '_inferred', [
            None if self.simulated is None or row.all() else ~row
            for row in (self.simulated if self.simulated is not None else [None] * k)])

    def __len__(self):
        return len(self.names)

    def inferred(self, index: int) -> np.ndarray | None:
        """``(M,)`` the gaits table ``index`` inferred rather than simulated; None: it
        simulated every one (a whole table)."""
        return self._inferred[index]

    def _rows(self, keep):
        """The optional per-table arrays cut to the tables ``keep`` (a slice or indices):
        ``(chained_runs, chained_falls, simulated)``."""
        return tuple(None if a is None else np.asarray(a)[keep]
                     for a in (self.chained_runs, self.chained_falls, self.simulated))

    @property
    def second_tier(self) -> np.ndarray:
        """``(K,)`` which tables are used only once one of them reproduced the robot's
        standing starts."""
        return self._second

    def first_tier(self) -> DamagePriors:
        """The tables used until a second-tier table has reproduced the robot's standing
        starts (itself when there is no second tier): the first ``K1`` tables, with the
        same indices."""
        if not self._second.any():
            return self
        if self._first_tier is None:
            keep = int(np.sum(~self._second))
            runs, falls, simulated = self._rows(slice(0, keep))
            object.__setattr__(self, '_first_tier', DamagePriors(
                tuple(self.names[:keep]), self.generic_reward[:keep], self.fallen[:keep],
                self.archive_checksum, runs, falls, None, simulated))
        return self._first_tier

    def chained(self, index: int):
        """``(gaits, runs, falls)`` of table ``index``'s chained runs (empty: none)."""
        return self._chained[index]

    @property
    def num_candidates(self) -> int:
        return self.generic_reward.shape[1]

    def without(self, name: str) -> DamagePriors:
        """The same tables less ``name`` (to measure a damage as if nobody foresaw it)."""
        keep = [i for i, n in enumerate(self.names) if n != name]
        runs, falls, simulated = self._rows(keep)
        return DamagePriors(tuple(self.names[i] for i in keep), self.generic_reward[keep],
                            self.fallen[keep], self.archive_checksum, runs, falls,
                            self._second[keep], simulated)

    def near(self, name: str, threshold: float = NEAR_DUPLICATE) -> list[str]:
        """The tables whose standing outcomes lie within ``threshold`` (rms, in units of
        :data:`RESIDUAL_SCALE`) of the table ``name``'s, ``name`` itself among them: its near
        duplicates, which a damage measured as if nobody foresaw it leaves out too. Raises
        KeyError for a name it does not hold."""
        if name not in self.names:
            raise KeyError(name)
        i = self.names.index(name)
        out = []
        for j, other in enumerate(self.names):
            stand = ~(self.fallen[i] | self.fallen[j])
            diff = (self.generic_reward[j, stand] - self.generic_reward[i, stand]) \
                / RESIDUAL_SCALE
            if j == i or np.sqrt(np.mean(diff ** 2)) < threshold:
                out.append(other)
        return out

    def check_archive(self, params) -> None:
        """Raise :class:`DamagePriorError` unless the tables are for these gaits."""
        if len(params) != self.num_candidates or params_checksum(params) \
                != self.archive_checksum:
            raise DamagePriorError(
                f'damage priors are for another archive ({self.num_candidates} gaits, '
                f'checksum {self.archive_checksum[:12]}); this one has {len(params)} gaits, '
                f'checksum {params_checksum(params)[:12]}: rebuild them with '
                '`make priors` (scripts/build_priors.py)')

    def select(self, base_gr, indices, observed, fall_indices=(), fallen=(),
               max_misfit=DEFAULT_MAX_MISFIT, standing=(),
               max_misfit_reproduced=DEFAULT_MAX_MISFIT_REPRODUCED) -> Selection:
        """The prior that best explains the steps seen: the intact map or a table.

        Args:
            base_gr: ``(M, k)`` the archive's own generic rewards (the intact map).
            indices, observed: the gaits learnt and their generic rewards ``(N, k)``.
            fall_indices, fallen: every step's gait and whether it fell.
            max_misfit: a table whose median squared error (units of RESIDUAL_SCALE) over the
                steps is above this is not used (of an even number of steps, the lower of the
                two middle errors); None: no table is.
            standing: ``(N,)`` which of the learnt steps started from a standing start (empty:
                none). Their errors weigh :data:`STANDING_PRECISION` times more, and a table
                that reproduced them (:data:`REPRODUCED`, :data:`REPRODUCED_SHARE`) is used up to
                ``max_misfit_reproduced`` instead of ``max_misfit``.
        """
        indices = np.asarray(indices, dtype=int).reshape(-1)
        if not indices.size or not len(self):
            return INTACT
        observed = np.asarray(observed, dtype=float).reshape(indices.size, -1)
        k = observed.shape[1]
        fall_indices = np.asarray(fall_indices, dtype=int).reshape(-1)
        fallen = np.asarray(fallen, dtype=bool).reshape(-1)
        # A gait seen falling says nothing reliable about where it goes: its displacement
        # is the tumble's. Falls are judged by the fall term instead.
        keep = ~np.isin(indices, fall_indices[fallen])
        scale = RESIDUAL_SCALE[:k] if k <= RESIDUAL_SCALE.size else np.ones(k) * 0.1
        # Only the gaits seen are read: (1 + K, steps) slices, never whole tables.
        seen = indices[keep]
        predicted = np.concatenate([np.asarray(base_gr, dtype=float)[None, seen, :k],
                                    self.generic_reward[:, seen, :k]])
        falls = np.concatenate([np.zeros((1, fall_indices.size), bool),
                                self.fallen[:, fall_indices]])
        r = (observed[keep][None] - predicted) / scale
        q = np.sum(r * r, axis=2)  # (tables, steps)
        standing = np.asarray(standing, dtype=bool).reshape(-1)
        if standing.size not in (0, indices.size):
            raise ValueError(f'standing has {standing.size} flags for {indices.size} steps')
        standing = standing[keep] if standing.size else np.zeros(q.shape[1], bool)
        # Robust: a step is explained by the table up to the chaining error, or is one of a
        # few surprises (a gait chained from an odd posture) that count for little. A step
        # from a standing start is no chaining: the table's own experiment.
        weighed = np.where(standing, STANDING_PRECISION ** 2, 1.0) * q
        wide = OUTLIER_SCALE ** 2
        loglik = np.logaddexp(np.log1p(-OUTLIER_FRACTION) - 0.5 * weighed,
                              np.log(OUTLIER_FRACTION) - 0.5 * k * np.log(wide)
                              - 0.5 * weighed / wide).sum(axis=1)
        # The lower median: the first step (from a standing start, where the right table is
        # exact) and one chained surprise must not make a mean of 0.02 and 15 (a gait
        # chained from an odd posture) that sets the right table aside (docs/notebook.md).
        misfit = (np.sort(q, axis=1)[:, (q.shape[1] - 1) // 2] / k if q.shape[1]
                  else np.zeros(len(predicted)))
        p = np.where(falls, P_FALL_IF_FALLS, P_FALL_IF_STANDS)
        loglik += np.sum(np.where(fallen, np.log(p), np.log1p(-p)), axis=1)
        best = int(np.argmax(loglik))
        reproduced = bool(best and standing.any() and np.mean(
            q[best, standing] / k < REPRODUCED) >= REPRODUCED_SHARE)
        if max_misfit is not None and reproduced:
            max_misfit = max(max_misfit, max_misfit_reproduced)
        if best == 0 or max_misfit is None or misfit[best] > max_misfit:
            return Selection(None, 'intact', float(misfit[0]))
        return Selection(best - 1, self.names[best - 1], float(misfit[best]), reproduced)

    def save(self, path) -> None:
        """Write the tables (``.npz``; atomic: a reader never sees half a file)."""
        chained = {} if self.chained_runs is None else {
            'chained_runs': np.asarray(self.chained_runs).astype(np.uint16),
            'chained_falls': np.asarray(self.chained_falls).astype(np.uint16)}
        if self.simulated is not None:
            chained['simulated'] = np.asarray(self.simulated, bool)
        atomic_write(path, lambda handle: np.savez_compressed(
            handle, names=np.array(self.names),
            generic_reward=self.generic_reward.astype(np.float32),
            fallen=self.fallen.astype(bool), archive_checksum=np.array(self.archive_checksum),
            format_version=np.array(FORMAT_VERSION), reproduce_only=self._second, **chained))


def load_damage_priors(path, params=None) -> DamagePriors:
    """Read a file written by :meth:`DamagePriors.save`; with ``params`` (the archive's
    gaits), also check that the tables are for that archive. Raises DamagePriorError."""
    path = Path(path)
    if not path.is_file():
        raise DamagePriorError(f'damage priors {path}: no such file')
    try:
        check_npz_size(path)
    except NpzRefused as exc:
        raise DamagePriorError(f'damage priors {exc}') from None
    try:
        with np.load(path, allow_pickle=False) as npz:
            version = int(npz['format_version'])
            if version != FORMAT_VERSION:
                raise DamagePriorError(f'damage priors {path}: format {version}, this '
                                       f'version reads {FORMAT_VERSION}')
            # Chained runs are optional (files from before them have none).
            chained = [npz[key].astype(int) if key in npz.files else None
                       for key in ('chained_runs', 'chained_falls')]
            second = npz['reproduce_only'] if 'reproduce_only' in npz.files else None
            simulated = npz['simulated'] if 'simulated' in npz.files else None
            priors = DamagePriors(tuple(str(n) for n in npz['names']),
                                  npz['generic_reward'].astype(float),
                                  npz['fallen'].astype(bool), str(npz['archive_checksum']),
                                  *chained, second, simulated)
    except DamagePriorError:
        raise
    except Exception as exc:  # truncated, not an npz, missing arrays
        raise DamagePriorError(f'damage priors {path}: unreadable ({exc})') from None
    if params is not None:
        priors.check_archive(params)
    return priors


def priors_path(archive_path, library=False) -> Path:
    """Where an archive's damage priors are kept: ``<archive>_priors.npz`` beside it;
    ``library``: its damage library, ``<archive>_library.npz`` (``scripts/build_library.py``)."""
    archive_path = Path(archive_path)
    return archive_path.with_name(f"{archive_path.stem}_{'library' if library else 'priors'}.npz")


def resolve_priors(value, archive_path, params) -> DamagePriors | None:
    """A ``priors`` parameter's tables: ``none`` (or '') none; ``auto`` those beside the
    archive if there are (else none); ``library`` the damage library beside it (which must
    be there); anything else a path, which must exist and match."""
    value = (value or '').strip()
    if value in ('', 'none'):
        return None
    if value == 'auto':
        path = priors_path(archive_path)
        return load_damage_priors(path, params) if path.is_file() else None
    if value == 'library':
        path = priors_path(archive_path, library=True)
        if not path.is_file():
            raise DamagePriorError(f'no damage library beside the archive ({path}): build it '
                                   'with `make library` and assemble it (mapbuild/README.md)')
        return load_damage_priors(path, params)
    return load_damage_priors(value, params)
