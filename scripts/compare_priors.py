"""Mixing the damage priors against choosing one, through the product's decision loop.

Every run is one replicate of the experiment runner (``sela-experiment hexapod``: its SELA
drives the ``MissionStepper`` that the ``sela_adapter`` node runs, with the damage detector,
the planner node's default map and the node's defaults): the PyBullet hexapod damaged from
the start, position observations with noise seeded as the ``sim_bridge`` node's ``seed``, a
fallen robot righted where it lies. Methods:

* ``select``: one table chosen, or the intact map (``priors.weights.sd`` none);
* ``mixture``: the tables mixed by weights fitted to the steps (``priors.weights.sd`` 1);
* ``caution``: the same, with ``acquisition.caution`` 0.15 m: the node's defaults (every
  other method runs with caution none, the paper's rule); ``caution-0.1``, ``caution-0.2``,
  ``caution-0.3``: other settings of it;
* ``progress-1.0``, ``progress-2.0``: ``caution`` with each gait scored by its progress along
  the path (``acquisition.progress``, the weight of the distance off the path);
  ``affine-0.5-progress-1.0``, ``affine-0.5-progress-2.0``: the same with ``gp.mean.affine``
  0.5; ``affine-0.5-progress-1.0-h1``: that with one step looked ahead (``planner.horizon`` 1);
* ``affine-<sd>``: ``caution`` with the affine map of the prior mean (``gp.mean.affine``);
  ``affine-0.5-descriptor-<sd>``: its scale linear in the gait's descriptor too
  (``gp.mean.descriptor``);
* ``reach-<g>``: ``caution`` with the waypoint set at ``g`` times the reach the robot's steps
  have shown (``planner.reach``); ``affine-0.5-reach-<g>``: the same with ``gp.mean.affine`` 0.5;
* ``hyper-<sd>``: ``caution`` with the GPs' kernel length and signal variance learnt from the
  steps (``gp.hyper.sd``); ``hyper-<sd>-affine``: that with ``gp.mean.affine`` 0.5;
* ``aprol-<r>``: ``caution`` with each gait scored by its chance of landing within ``r`` m of
  the waypoint (``acquisition.reach``); ``affine-0.5-aprol-<r>``: the same with
  ``gp.mean.affine`` 0.5;
* ``alpha-0.0``: ``caution`` with no UCB bonus (``acquisition.ucb.alpha`` 0);
* ``none``: the intact map only (``--priors none``);
* ``library-select``, ``library``: one table chosen, or the tables mixed, from a damage
  library (``--library``, ``scripts/build_library.py``), each damage foreseen by no table
  measured with its own condition and the conditions near it left out (:func:`leave_out`);
* ``library-own``: the tables mixed from the whole library, the damage's own condition in
  (a damage the library foresaw: what a table for it gives); ``library-own-caution``: the
  same with ``caution``'s settings (what a self-model whose hypotheses are the library's
  conditions gives at most, its simulations all done in advance);
* ``bound-own``: no damage priors, the GPs' prior mean the damage's own table (its library
  condition, or its whole oracle table): SELA on a damage known in advance;
* ``bound-fit``: no damage priors, the prior mean the best mixture of the library's tables
  (intact map plus non-negative weights on their deviations; the damage's own condition and
  its near duplicates left out) fitted to every gait known of the damage, which no robot
  knows: the most that the shipped mixture's model could give (:func:`bound_table`);
* ``bound-fit-signed``: the same with weights of any sign, every linear combination of the
  library's tables: the most that any mixture of them could give.

Damages are foreseen (their table ships beside the map) or not (``/own-left-out``: the single
leg with its own table removed from the priors; every other damage is in no table). The
oracle's median steps per damage and goal come from the campaigns in ``docs/results``.
Runs are appended to ``--out`` (JSON lines) as they finish, and a rerun skips those done::

    nice -n 15 .venv/bin/python scripts/compare_priors.py --seeds 3 \\
        --out docs/results/priors_combination/runs.jsonl --markdown docs/priors_combination.md
"""
from __future__ import annotations

import argparse
import functools
import glob
import json
import os
import statistics
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import NamedTuple

#: The repository this script is in: its sela_ros is the one run (and, through the workers'
#: pool, the one each worker runs), not a copy installed elsewhere.
ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from sela_ros import single_blas_thread  # noqa: E402

single_blas_thread()  # before numpy

import numpy as np  # noqa: E402

SINGLE_LEGS = ('front_left', 'middle_left', 'rear_left', 'front_right', 'middle_right',
               'rear_right')
#: (case, damage, whether its own table is left out of the priors).
UNFORESEEN = tuple((f'remove:{leg}/own-left-out', f'remove:{leg}', True)
                   for leg in SINGLE_LEGS) + tuple((d, d, False) for d in (
                       'remove:front_left,remove:rear_right',
                       'remove:middle_left,remove:middle_right',
                       'shorten:front_left:0.5',
                       'block:rear_right.knee=0.3',
                       'remove:front_left,remove:middle_left',
                       'shorten:rear_left:0.7,block:front_right.knee=-0.2',
                       # Between the library's grid points (lengths 0.3, 0.6, 0.8; knees
                       # at -0.4, 0, 0.4; limp hips; pairs at 0.6), or beside them (a limp
                       # knee, a leg removed and another shortened).
                       'shorten:rear_left:0.7', 'shorten:middle_left:0.45',
                       'shorten:rear_right:0.7', 'shorten:front_right:0.45',
                       'block:front_left.knee=0.2', 'weaken:middle_left.hip_pitch=0.3',
                       'weaken:front_left.knee=0.0',
                       'shorten:front_left:0.7,shorten:middle_right:0.7',
                       'remove:rear_right,shorten:front_left:0.6'))
FORESEEN = tuple((f'remove:{leg}', f'remove:{leg}', False)
                 for leg in ('middle_right', 'front_left', 'rear_right'))
#: Deviations no table holds and the map was not built on: the ground's friction and a payload,
#: alone and with a leg removed or shortened (their oracles: build_library.py --oracle-only).
DEVIATIONS = tuple((base + dev, base + dev, False)
                   for base in ('', 'remove:rear_left,', 'shorten:front_right:0.5,')
                   for dev in ('friction:0.5', 'friction:0.3', 'payload:1.0@0.08,0.05'))
GOALS = ((2.0, 2.0), (-2.0, 1.5), (1.5, -2.0), (2.5, 0.5))
METHODS = {'select': {'priors.weights.sd': 'none'}, 'mixture': {'priors.weights.sd': 1.0},
           'none': None, 'library-select': {'priors.weights.sd': 'none'},
           'library': {'priors.weights.sd': 1.0}, 'library-own': {'priors.weights.sd': 1.0},
           'library-own-caution': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                                   'gp.mean.affine': 'none'},
           'oracle': None, 'oracle-restricted': None, 'bound-own': None, 'bound-fit': None,
           'bound-fit-signed': None,
           'caution': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                       'gp.mean.affine': 'none'},
           **{f'selfmodel-{g}-{d}{t}': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                                        'gp.mean.affine': 'none',
                                        'self_model': (g, g // 2, d, not t)}
              for g in (300, 600) for d in (0, 3, 5) for t in ('', '-second')},
           **{f'selfmodel-600-5-refine{r}': {'priors.weights.sd': 1.0,
                                             'acquisition.caution': 0.15,
                                             'gp.mean.affine': 'none',
                                             'self_model': (600, 300, 5, True, r)}
              for r in (0, 100, 200, 400)},
           'alpha-0.0': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                         'gp.mean.affine': 'none', 'acquisition.ucb.alpha': 0.0},
           **{f'caution-{v}': {'priors.weights.sd': 1.0, 'acquisition.caution': v,
                               'gp.mean.affine': 'none'}
              for v in (0.1, 0.2, 0.3)},
           **{f'affine-{v}': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                              'gp.mean.affine': v} for v in (0.25, 0.5, 1.0)},
           **{f'affine-{v}-nocaution': {'priors.weights.sd': 1.0, 'gp.mean.affine': v}
              for v in (0.5,)},
           **{f'progress-{w}': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                                'gp.mean.affine': 'none', 'acquisition.progress': w}
              for w in (1.0, 2.0)},
           **{f'affine-0.5-progress-{w}': {'priors.weights.sd': 1.0,
                                           'acquisition.caution': 0.15,
                                           'gp.mean.affine': 0.5, 'acquisition.progress': w}
              for w in (1.0, 2.0)},
           **{f'affine-0.5-progress-{w}-h1': {'priors.weights.sd': 1.0,
                                              'acquisition.caution': 0.15,
                                              'gp.mean.affine': 0.5, 'acquisition.progress': w,
                                              'planner.horizon': 1}
              for w in (1.0,)},
           **{f'affine-0.5-descriptor-{v}': {'priors.weights.sd': 1.0,
                                             'acquisition.caution': 0.15,
                                             'gp.mean.affine': 0.5,
                                             'gp.mean.descriptor': v}
              for v in (0.5, 1.0, 2.0)},
           **{f'reach-{g}': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                             'gp.mean.affine': 'none', 'planner.reach': g}
              for g in (1.0, 1.5, 2.0)},
           **{f'affine-0.5-reach-{g}': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                                        'gp.mean.affine': 0.5, 'planner.reach': g}
              for g in (1.0, 1.5, 2.0)},
           **{f'hyper-{v}': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                             'gp.mean.affine': 'none', 'gp.hyper.sd': v}
              for v in (0.5, 1.0)},
           **{f'hyper-{v}-affine': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                                    'gp.mean.affine': 0.5, 'gp.hyper.sd': v}
              for v in (0.5, 1.0)},
           **{f'aprol-{r}': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                             'gp.mean.affine': 'none', 'acquisition.reach': r}
              for r in (0.15, 0.3, 0.45)},
           **{f'affine-0.5-aprol-{r}': {'priors.weights.sd': 1.0,
                                        'acquisition.caution': 0.15, 'gp.mean.affine': 0.5,
                                        'acquisition.reach': r}
              for r in (0.15, 0.3, 0.45)},
           **{f'fallcost-{c}': {'priors.weights.sd': 1.0, 'acquisition.caution': 0.15,
                                'gp.mean.affine': 'none', 'fall.risk.cost': c}
              for c in (2.0,)},
           **{f'affine-0.5-aprol-0.3-fallcost-{c}': {
               'priors.weights.sd': 1.0, 'acquisition.caution': 0.15, 'gp.mean.affine': 0.5,
               'acquisition.reach': 0.3, 'fall.risk.cost': c} for c in (2.0,)}}
#: Methods only reported (``--report-only``), their runs made by an earlier version of the code:
#: ``affine-0.5-ungated``: the affine map of the prior mean always in use once a step stood
#: (commit "learning: an affine map of the prior mean learnt from the steps; ...");
#: ``*-progress-1.0*-lcb``: ``acquisition.progress`` 1 with the progress along the path one
#: standard deviation of the landing short of its mean (commit "learning: progress along the
#: path counted one standard deviation short when caution is on");
#: ``affine-0.5-descriptor-1.0-margin-3``: ``affine-0.5-descriptor-1.0`` with
#: ``sela.AFFINE_MIN_SCORE`` 3 (docs/learning_the_damage.md has the command);
#: ``*-reach-1.5-max-floor-0.3``: ``*-reach-1.5`` with the robot's reach the largest step
#: shown (``reach.REACH_QUANTILE`` 1) and the nearest waypoint 0.3 m (``reach.REACH_FLOOR``);
#: ``hyper-*-falls-in``: ``hyper-*`` with the kernel fitted to every step, tumbles included
#: (commit "learning: the GPs' kernel length and signal variance learnt from the steps'
#: residuals ..."); ``hyper-0.5-length``: ``hyper-0.5`` with the signal variance fixed
#: (``hyper.VARIANCE_FACTORS`` (1,): docs/learning_the_damage.md has the command);
#: ``hyper-0.5-configured-variance``: ``hyper-0.5`` with ``sela.HYPER_VARIANCE_LEARNT`` False;
#: ``aprol-0.3-floor-0.1``: ``aprol-0.3`` with ``acquisition.REACH_MIN_CHANCE`` 0.1 and two
#: steps ahead scored by the product of both steps' chances times 1 - each fall risk (commit
#: "learning: acquisition.reach scores each gait by its chance of landing within reach ...");
#: ``disappointment``: ``caution`` with the untried gaits' predicted steps shrunk by the share
#: of untried gaits that disappointed (a patch of ``SELA._posterior``: the command is in
#: docs/learning_the_damage.md); ``second-inflated``: ``caution`` with the second of two steps
#: always scored by the expected distance under the untried gaits' learnt error, caution on or
#: not (a patch of ``SELA._two_step_choice``, the command there too);
#: ``slow-0.55-affine-0.5-aprol-0.3``: ``affine-0.5-aprol-0.3`` with the affine map and the
#: chance of reaching in use only once three steps that stood covered at most 0.55 of the
#: distance the prior in use predicted for them (a patch of ``SELA._affine_weights`` and
#: ``SELA.ask``: the command is in docs/learning_the_damage.md).
REPORTED_ONLY = ('affine-0.5-ungated', 'progress-1.0-lcb', 'affine-0.5-progress-1.0-lcb',
                 'affine-0.5-progress-1.0-h1-lcb', 'affine-0.5-descriptor-1.0-margin-3',
                 'reach-1.5-max-floor-0.3', 'affine-0.5-reach-1.5-max-floor-0.3',
                 'hyper-0.5-falls-in', 'hyper-1.0-falls-in', 'hyper-0.5-affine-falls-in',
                 'hyper-0.5-length', 'hyper-0.5-configured-variance',
                 'aprol-0.3-floor-0.1', 'disappointment', 'second-inflated',
                 'slow-0.55-affine-0.5-aprol-0.3')
#: The oracle (the experiments' ``oracle``: it knows the damaged robot's outcomes and its true
#: pose) with what is known of the damage (:func:`build_library.known_outcomes`): a whole
#: table, else the gaits the library evaluated; ``oracle-restricted``: a whole table cut to
#: those gaits, to measure what the oracle loses with them alone.
ORACLE_METHODS = ('oracle', 'oracle-restricted')
#: Methods that take their tables from ``--library``, each damage with its own condition and
#: its near duplicates left out (:func:`leave_out`).
LIBRARY_METHODS = ('library-select', 'library', 'library-own', 'library-own-caution')
#: Methods given the whole library, each damage's own condition in (a damage it foresaw).
OWN_LIBRARY_METHODS = ('library-own', 'library-own-caution')
#: Methods whose prior mean is a table of the damage (:func:`bound_table`; need --library).
BOUND_METHODS = ('bound-own', 'bound-fit', 'bound-fit-signed')
CAMPAIGNS = ('campaign_priors', 'campaign_unforeseen', 'campaign_oracle_one_side',
             'campaign_oracle_between', 'campaign_oracle_combined')


def oracle_medians():
    """``{(canonical damage, (gx, gy)): median steps}`` of the oracle in docs/results."""
    from sim_bridge.damage import parse_damage

    out = {}
    for camp in CAMPAIGNS:
        pattern = str(ROOT / 'docs' / 'results' / camp / '*' / '*' / '*' / 'results.json')
        for path in sorted(glob.glob(pattern)):
            with open(path) as handle:
                doc = json.load(handle)
            oracle = doc.get('methods', {}).get('oracle')
            if oracle:
                key = (parse_damage(doc['parameters']['damage']).canonical(),
                       tuple(float(v) for v in doc['parameters']['goal']))
                out[key] = float(np.median(oracle['steps']))
    return out


def library_cases(path=None):
    """Every condition of the library file ``path`` (None: of the library's build plan) as
    a damage nobody foresaw (measured with its own table and its near duplicates left out),
    then the unforeseen cases of :data:`UNFORESEEN` that are no condition of it (between its
    grid points, combinations)."""
    from sela_ros.core.learning.damage_priors import load_damage_priors
    from sim_bridge.damage import parse_damage

    if path:
        names = load_damage_priors(path).names
    else:
        sys.path.insert(0, str(ROOT / 'scripts'))
        import build_library
        names = build_library.conditions()
    held = {parse_damage(n).canonical() for n in names}
    return tuple((f'{n}/own-left-out', n, True) for n in names) + tuple(
        c for c in UNFORESEEN if '/own-left-out' not in c[0]
        and parse_damage(c[1]).canonical() not in held)


def leave_out(priors, damage):
    """``priors`` less ``damage``'s own condition (the same damage, canonically) and every
    table nearer to it than ``NEAR_DUPLICATE``; returns ``(priors, names left out)``."""
    from sela_ros.experiments.workers import own_and_near

    names = own_and_near(priors, damage)
    for name in names:
        priors = priors.without(name)
    return priors, names


@functools.lru_cache(maxsize=1)
def second_tier_cases():
    """The damages of the shipped priors' second tier (the library's conditions), each
    measured with the priors as they ship: ``(damage, damage, False)``."""
    from sela_ros.core.learning import resolve_priors
    from sela_ros.core.storage import default_archive_path, load_archive

    shipped = resolve_priors('auto', default_archive_path(),
                             load_archive(default_archive_path()).params)
    if shipped is None:
        return ()
    return tuple((n, n, False) for n, second in zip(shipped.names, shipped.second_tier)
                 if second)


def library_priors(whole, cases, scratch):
    """``{case label: (path of its priors file, names left out)}``: a foreseen case keeps
    the whole library; every other one is measured as if no condition of the library were
    it or near it (:func:`leave_out`). The files are written to ``scratch``."""
    out = {}
    for n, case in enumerate(cases):
        kept, names = (whole, []) if case in FORESEEN else leave_out(whole, case[1])
        path = os.path.join(scratch, f'{n}.npz')
        kept.save(path)
        out[case[0]] = (path, names)
        print(f'{case[0]}: {len(names)} of {len(whole)} library tables left out '
              f'({", ".join(names) or "none"})', flush=True)
    return out


def run_one(shipped, case, goal, method, seed, args, library=None):
    """One mission through the experiment runner (``sela-experiment hexapod``'s SELA
    replicate: the node's stepper, detector, planner and defaults), the observation noise
    seeded as the ``sim_bridge`` node's ``seed``; the method sets the damage priors and
    ``priors.weights.sd``."""
    from sela_ros.core.storage import default_archive_path
    from sela_ros.experiments.hexapod import Job, run_method

    label, damage, leave_out_own = case
    if method in ORACLE_METHODS:
        return run_oracle(case, goal, method, seed, args)
    left_out, priors_value, prior_mean = [], 'auto', None
    if method in BOUND_METHODS:
        prior_mean = bound_table(damage, method, args.library)
        if prior_mean is None:
            return None
        priors_value, leave_out_own = 'none', False
    elif method in OWN_LIBRARY_METHODS:
        priors_value, leave_out_own = args.library, False
    elif method in LIBRARY_METHODS:
        priors_value, left_out = library[label]
        leave_out_own = False  # the library's file for this damage has it left out
    elif METHODS[method] is None:
        priors_value, leave_out_own = 'none', False
    settings = METHODS[method] or {}
    extra = {} if args.lookahead is None else {'lookahead': args.lookahead}
    job = Job('sela', np.random.SeedSequence(seed), str(default_archive_path()), damage,
              tuple(goal), noise_std=args.noise_std, max_steps=args.max_steps,
              priors=priors_value, leave_out_own=leave_out_own, noise_seed=seed,
              weights_sd=settings.get('priors.weights.sd'),
              caution=settings.get('acquisition.caution', 'none'), prior_mean=prior_mean,
              mean_affine=settings.get('gp.mean.affine', 'none'),
              progress=settings.get('acquisition.progress', 'none'),
              mean_affine_descriptor=settings.get('gp.mean.descriptor', 'none'),
              hyper_sd=settings.get('gp.hyper.sd', 'none'),
              reach_chance=settings.get('acquisition.reach', 'none'),
              horizon=settings.get('planner.horizon'), trace=args.trace,
              reach=settings.get('planner.reach', 'none'),
              alpha=settings.get('acquisition.ucb.alpha'),
              self_model=self_model_config(settings.get('self_model')),
              **extra)
    out = run_method(job)
    foreseen = is_foreseen(label, method) if method in (*OWN_LIBRARY_METHODS, 'bound-own') else (
        priors_value == 'auto' and not leave_out_own and damage in shipped)
    return {'case': label, 'damage': damage, 'foreseen': foreseen, 'goal': list(goal),
            'method': method, 'seed': seed, 'success': out['success'], 'steps': out['steps'],
            'falls': out['falls'], 'wall_seconds': round(out['wall_seconds'], 2),
            'behaviors': out['behaviors'],
            **({'left_out': left_out} if method in LIBRARY_METHODS else {}),
            **({'steps_detail': out['steps_detail']} if 'steps_detail' in out else {})}


def self_model_config(value):
    """A method's ``self_model`` ``(gaits, covering, delay steps)`` as the runner takes it
    (None: no self-model)."""
    from sela_ros.core.learning.self_model import SelfModelConfig

    return None if value is None else SelfModelConfig(*value)


_ORACLE_TABLES = {}
_BOUND_TABLES = {}


def best_mixture(intact, tables, truth, rows, scale, signed=False):
    """``intact + sum_k w_k (tables[k] - intact)`` with the weights nearest, in least
    squares over ``rows`` of the outputs divided by ``scale``, to ``truth``: ``w >= 0`` (the
    shipped mixture's model), or any sign (``signed``: every linear combination)."""
    from scipy.optimize import nnls

    deviations = np.asarray(tables, dtype=float) - intact[None]
    design = (deviations[:, rows] / scale).reshape(len(deviations), -1).T
    target = ((truth[rows] - intact[rows]) / scale).reshape(-1)
    weights = np.linalg.lstsq(design, target, rcond=None)[0] if signed else \
        nnls(design, target)[0]
    return intact + np.tensordot(weights, deviations, axes=1)


@functools.lru_cache(maxsize=2)
def _bound_sources(library_path):
    """``(archive, shipped priors, library)``, loaded once per process."""
    from sela_ros.core.learning import resolve_priors
    from sela_ros.core.storage import default_archive_path, load_archive

    archive = load_archive(default_archive_path())
    return (archive, resolve_priors('auto', default_archive_path(), archive.params),
            resolve_priors(library_path, default_archive_path(), archive.params))


def bound_table(damage, method, library_path):
    """The prior mean of a bound method on ``damage`` (``(M, 3)``), or None when nothing of
    the damage is known (kept per process). ``bound-own``: the library's table of the
    damage where it holds it, else its whole oracle table. ``bound-fit``: the intact map
    plus the mixture of the library's deviations from it (the damage's own condition and its
    near duplicates left out, :func:`leave_out`) nearest, in units of the chaining error, to
    what is known of the damage on every gait known standing (:func:`best_mixture`; weights
    of any sign for ``bound-fit-signed``)."""
    key = (damage, method)
    if key not in _BOUND_TABLES:
        sys.path.insert(0, str(ROOT / 'scripts'))
        import build_library

        from sela_ros.core.learning.damage_priors import RESIDUAL_SCALE
        from sim_bridge.damage import parse_damage

        archive, shipped, whole = _bound_sources(library_path)
        intact = archive.generic_reward[:, :3]
        known = build_library.known_outcomes(archive, damage, shipped=shipped)
        canonical = parse_damage(damage).canonical()
        own = [i for i, n in enumerate(whole.names) if parse_damage(n).canonical() == canonical]
        if method == 'bound-own' and own:
            _BOUND_TABLES[key] = whole.generic_reward[own[0]][:, :3].astype(float)
        elif known is None:
            _BOUND_TABLES[key] = None
        elif method == 'bound-own':
            _BOUND_TABLES[key] = known[0]
        else:
            gr, fallen, where, _ = known
            kept, _ = leave_out(whole, damage)
            _BOUND_TABLES[key] = best_mixture(intact, kept.generic_reward[:, :, :3], gr,
                                              where & ~fallen, RESIDUAL_SCALE,
                                              signed=method == 'bound-fit-signed')
    return _BOUND_TABLES[key]



def oracle_table(damage, restrict):
    """``(generic_reward with FALLEN_GR where a gait falls or is not known, source)`` for
    the oracle on ``damage``, or None when nothing of it is known (kept per process)."""
    key = (damage, restrict)
    if key not in _ORACLE_TABLES:
        sys.path.insert(0, str(ROOT / 'scripts'))
        import build_library

        from sela_ros.core.learning import resolve_priors
        from sela_ros.core.storage import default_archive_path, load_archive
        from sela_ros.experiments.hexapod import FALLEN_GR

        archive = load_archive(default_archive_path())
        shipped = resolve_priors('auto', default_archive_path(), archive.params)
        known = build_library.known_outcomes(archive, damage, shipped=shipped,
                                             restrict=restrict)
        if known is None:
            _ORACLE_TABLES[key] = None
        else:
            gr, fallen, where, source = known
            _ORACLE_TABLES[key] = (np.where((fallen | ~where)[:, None], FALLEN_GR, gr), source)
    return _ORACLE_TABLES[key]


def run_oracle(case, goal, method, seed, args):
    """One oracle mission on the case's damage (None: nothing of the damage is known)."""
    from sela_ros.core.storage import default_archive_path
    from sela_ros.experiments.hexapod import Job, run_method

    label, damage, _ = case
    table = oracle_table(damage, method == 'oracle-restricted')
    if table is None:
        return None
    extra = {} if args.lookahead is None else {'lookahead': args.lookahead}
    job = Job('oracle', np.random.SeedSequence(seed), str(default_archive_path()), damage,
              tuple(goal), noise_std=args.noise_std, max_steps=args.max_steps,
              noise_seed=seed, oracle_gr=table[0], **extra)
    out = run_method(job)
    return {'case': label, 'damage': damage, 'foreseen': False, 'goal': list(goal),
            'method': method, 'seed': seed, 'success': out['success'], 'steps': out['steps'],
            'falls': out['falls'], 'wall_seconds': round(out['wall_seconds'], 2),
            'behaviors': out['behaviors'], 'oracle_table': table[1]}


def measured_oracle(runs, whole=None):
    """``{(canonical damage, goal): median steps}`` of the ``oracle`` runs in ``runs``;
    ``whole``: only those told a whole table (True) or only the others (False)."""
    from sim_bridge.damage import parse_damage

    steps = {}
    for r in runs:
        if r['method'] == 'oracle' and (whole is None or whole == r.get(
                'oracle_table', '').startswith('whole table')):
            key = (parse_damage(r['damage']).canonical(), tuple(float(v) for v in r['goal']))
            steps.setdefault(key, []).append(r['steps'])
    return {key: float(np.median(v)) for key, v in steps.items()}


def summarise(runs, oracle, methods):
    """Rows per case and method: successes, median steps, ratio to the oracle, falls."""
    from sim_bridge.damage import parse_damage

    rows = []
    cases = list(dict.fromkeys(r['case'] for r in runs))
    for case in cases:
        for method in methods:
            mine = [r for r in runs if r['case'] == case and r['method'] == method]
            if not mine:
                continue
            damage = parse_damage(mine[0]['damage']).canonical()
            ratios = []
            for goal in dict.fromkeys(tuple(r['goal']) for r in mine):
                steps = [r['steps'] for r in mine if tuple(r['goal']) == goal]
                o = oracle.get((damage, goal))
                if o:
                    ratios.append(statistics.median(steps) / o)
            with_oracle = [r for r in mine if (damage, tuple(r['goal'])) in oracle]
            rows.append({
                'case': case, 'method': method, 'runs': len(mine),
                'success': sum(r['success'] for r in mine),
                'median_steps': statistics.median(r['steps'] for r in mine),
                'median_steps_oracle_goals': statistics.median(
                    r['steps'] for r in with_oracle) if with_oracle else None,
                'oracle_median': statistics.median(
                    oracle[(damage, tuple(r['goal']))] for r in with_oracle)
                if with_oracle else None,
                'median_ratio': statistics.median(ratios) if ratios else None,
                'worst_ratio': max(ratios) if ratios else None,
                'median_falls': statistics.median(r['falls'] for r in mine),
                'falls': sum(r['falls'] for r in mine),
                'every_run': ' '.join(f"{r['steps']}{'F' * min(r['falls'], 9)}"
                                      + ('' if r['success'] else 'x') for r in mine)})
    return rows


def kind_of(damage):
    """The group a damage is reported in: its kind, single legs apart from pairs."""
    from sim_bridge.damage import parse_damage

    spec = parse_damage(damage)
    kinds = sorted({part.split(':')[0] for part in damage.split(',')})
    if len(kinds) > 1:
        return 'combined kinds'
    legs = len(spec.removed) + len(spec.shortened) + len(spec.blocked) + len(spec.weakened)
    return f"{kinds[0]}{', two legs' if legs > 1 else ''}"


#: The bar per condition (docs/damage_library.md): at every goal, this share of the runs
#: home, median steps at most this many times the oracle's (pairs of legs removed: the
#: second), median falls per run at most this.
BAR_SUCCESS, BAR_RATIO, BAR_RATIO_PAIR, BAR_FALLS = 0.95, 1.3, 1.5, 1.0


class Cell(NamedTuple):
    """One case and goal of one method."""
    case: str
    damage: str
    goal: tuple
    runs: int
    home: int
    median_steps: float
    oracle: float | None  # the oracle's median steps (None: no oracle)
    median_falls: float


def cells(runs, oracle, method):
    """Per case and goal of ``method``: its :class:`Cell`."""
    from sim_bridge.damage import parse_damage

    out = {}
    for r in runs:
        if r['method'] == method:
            out.setdefault((r['case'], r['damage'], tuple(r['goal'])), []).append(r)
    return [Cell(case, damage, goal, len(rs), sum(r['success'] for r in rs),
                 statistics.median(r['steps'] for r in rs),
                 oracle.get((parse_damage(damage).canonical(), goal)),
                 statistics.median(r['falls'] for r in rs))
            for (case, damage, goal), rs in out.items()]


def bar_table(runs, oracle, methods):
    """Per kind of damage and method: how many conditions meet the bar at every goal, and
    the median and worst of their goals' ratios to the oracle."""
    lines = ['| kind | method | conditions | runs | home | meet the bar | success >= 95 % '
             '| ratio <= bar | falls <= 1 | median ratio | worst ratio | falls |',
             '|' + '---|' * 12]
    for method in methods:
        per_case = {}
        for cell in cells(runs, oracle, method):
            per_case.setdefault(cell.case, []).append(cell)
        kinds = {}
        for cs in per_case.values():
            kinds.setdefault(kind_of(cs[0].damage), []).append(cs)
        for kind, conditions in sorted(kinds.items()):
            bar = BAR_RATIO_PAIR if kind == 'remove, two legs' else BAR_RATIO
            ok = [all(c.home >= BAR_SUCCESS * c.runs for c in cs) for cs in conditions]
            # Only the conditions with an oracle at every goal are judged on steps.
            timed = [all(c.oracle for c in cs) for cs in conditions]
            fast = [t and all(c.median_steps <= bar * c.oracle for c in cs)
                    for t, cs in zip(timed, conditions)]
            calm = [all(c.median_falls <= BAR_FALLS for c in cs) for cs in conditions]
            both = [a and b and c for a, b, c in zip(ok, fast, calm)]
            ratios = [c.median_steps / c.oracle for cs in conditions for c in cs if c.oracle]
            mine = [r for r in runs if r['method'] == method
                    and kind_of(r['damage']) == kind]
            lines.append(
                f"| {kind} | {method} | {len(conditions)} | {len(mine)} "
                f"| {sum(r['success'] for r in mine)} | {sum(both)} of {sum(timed)} "
                f"| {sum(ok)} | {sum(fast)} of {sum(timed)} (<= {bar:g}x) | {sum(calm)} "
                f"| {_fmt(statistics.median(ratios) if ratios else None)}x "
                f"| {_fmt(max(ratios) if ratios else None)}x "
                f"| {sum(r['falls'] for r in mine)} |")
    return '\n'.join(lines)


def figure(runs, oracle, methods, path):
    """Every condition's goals' ratios to the oracle, per method, grouped by kind."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    cases = sorted({r['case'] for r in runs if r['method'] in methods},
                   key=lambda c: (kind_of(c.split('/')[0]), c))
    fig, ax = plt.subplots(figsize=(12, 4.2), dpi=100)
    colours = ('#1b9e77', '#d95f02', '#7570b3', '#e7298a')
    for m, method in enumerate(methods):
        by_case = {}
        for c in cells(runs, oracle, method):
            if c.oracle:
                by_case.setdefault(c.case, []).append(c.median_steps / c.oracle)
        xs = [i + 0.25 * (m - (len(methods) - 1) / 2) for i, c in enumerate(cases)
              if c in by_case]
        ys = [statistics.median(by_case[c]) for c in cases if c in by_case]
        lo = [min(by_case[c]) for c in cases if c in by_case]
        hi = [max(by_case[c]) for c in cases if c in by_case]
        ax.vlines(xs, lo, hi, colors=colours[m % 4], linewidth=1)
        ax.plot(xs, ys, 'o', ms=3, color=colours[m % 4], label=method)
    ax.axhline(BAR_RATIO, color='grey', linestyle='--', linewidth=0.8)
    ax.axhline(1.0, color='black', linewidth=0.6)
    edges, last = [], None
    for i, c in enumerate(cases):
        kind = kind_of(c.split('/')[0])
        if kind != last:
            edges.append((i, kind))
            last = kind
    for i, kind in edges:
        ax.axvline(i - 0.5, color='lightgrey', linewidth=0.6)
        ax.text(i - 0.4, 0.05, kind, rotation=90, fontsize=7,
                transform=ax.get_xaxis_transform(), va='bottom')
    ax.set_xticks([])
    ax.set_xlabel(f'{len(cases)} damages, grouped by kind; each with its own table and its '
                  'near duplicates left out (library-own, bound-own: the own table in)')
    ax.set_ylabel("median steps / oracle's\n(dot: median of 3 goals; line: their range)")
    ax.legend(loc='upper right', fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _fmt(v, spec='{:.2f}'):
    return '-' if v is None else spec.format(v)


def table(rows):
    lines = ['| damage | foreseen | method | success | median steps | oracle | median ratio '
             '| worst ratio | median falls/run | falls | every run (steps, F per fall, x '
             'failed) |', '|' + '---|' * 11]
    for r in rows:
        foreseen = 'yes' if is_foreseen(r['case'], r['method']) else 'no'
        lines.append(f"| {r['case']} | {foreseen} | {r['method']} | {r['success']}/{r['runs']} "
                     f"| {r['median_steps']:g} | {_fmt(r['oracle_median'], '{:g}')} "
                     f"| {_fmt(r['median_ratio'])}x | {_fmt(r['worst_ratio'])}x "
                     f"| {r['median_falls']:g} | {r['falls']} | {r['every_run']} |")
    return '\n'.join(lines)


def is_foreseen(case, method):
    """Whether ``method`` ran ``case`` with a table of that damage: a foreseen case (the
    shipped priors' second tier included), or a condition of the library run with the whole
    library (:data:`OWN_LIBRARY_METHODS`)."""
    return case in {c[0] for c in FORESEEN + second_tier_cases()} or method == 'bound-own' or (
        method in OWN_LIBRARY_METHODS and case.endswith('/own-left-out'))


def totals(rows, runs, methods):
    """Per method and group (unforeseen, foreseen): the headline figures."""
    lines = ['| group | method | runs | success | median steps | median of the cells\' '
             'ratios | worst cell ratio | falls |', '|' + '---|' * 8]
    for group, foreseen in (('unforeseen', False), ('foreseen', True)):
        for method in methods:
            mine = [r for r in runs if r['method'] == method
                    and is_foreseen(r['case'], method) == foreseen]
            cells = [r for r in rows if r['method'] == method
                     and is_foreseen(r['case'], method) == foreseen
                     and r['median_ratio'] is not None]
            if not mine:
                continue
            median_ratio = statistics.median(c['median_ratio'] for c in cells) if cells \
                else None
            lines.append(
                f"| {group} | {method} | {len(mine)} | {sum(r['success'] for r in mine)} "
                f"| {statistics.median(r['steps'] for r in mine):g} "
                f"| {_fmt(median_ratio)}x "
                f"| {_fmt(max((c['worst_ratio'] for c in cells), default=None))}x "
                f"| {sum(r['falls'] for r in mine)} |")
    return '\n'.join(lines)


def paired(runs, methods):
    """Per group, each method against the first on the same (damage, goal, seed): total
    steps over the runs both made, and how many runs it took fewer, as many, more steps."""
    if len(methods) < 2:
        return ''
    first = methods[0]
    by_key = {(r['case'], tuple(r['goal']), r['seed'], r['method']): r for r in runs}
    lines = [f'| group | method | runs paired | total steps ({first}) | total steps | fewer '
             '| as many | more | falls (' + first + ') | falls |', '|' + '---|' * 10]
    for group, foreseen in (('unforeseen', False), ('foreseen', True)):
        for method in methods[1:]:
            pairs = [(by_key[(c, g, s, first)], r) for (c, g, s, m), r in by_key.items()
                     if m == method and is_foreseen(c, method) == foreseen
                     and (c, g, s, first) in by_key]
            if not pairs:
                continue
            a = [p[0]['steps'] for p in pairs]
            b = [p[1]['steps'] for p in pairs]
            lines.append(f'| {group} | {method} | {len(pairs)} | {sum(a)} | {sum(b)} '
                         f'| {sum(y < x for x, y in zip(a, b))} '
                         f'| {sum(y == x for x, y in zip(a, b))} '
                         f'| {sum(y > x for x, y in zip(a, b))} '
                         f"| {sum(p[0]['falls'] for p in pairs)} "
                         f"| {sum(p[1]['falls'] for p in pairs)} |")
    return '\n'.join(lines)


def _runs(todo, shipped, args, library):
    """Each run's record as it finishes: here, one after another, or on a process pool of
    ``args.workers``."""
    if args.workers <= 1:
        for case, goal, method, seed in todo:
            yield run_one(shipped, case, goal, method, seed, args, library)
        return
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = [pool.submit(run_one, shipped, case, goal, method, seed, args, library)
                   for case, goal, method, seed in todo]
        for future in as_completed(futures):
            yield future.result()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--seeds', type=int, default=3, help='runs per cell (seeds 0..N-1)')
    parser.add_argument('--workers', type=int, default=1,
                        help='runs at once, one process each (default %(default)s)')
    parser.add_argument('--first-seed', type=int, default=0,
                        help='start at this seed (to share the seeds among processes, each '
                             'with its own --out)')
    parser.add_argument('--methods', default='select,mixture',
                        help=f'comma-separated, of {sorted(METHODS)} (default %(default)s)')
    parser.add_argument('--cases', default='all',
                        help="'all', 'unforeseen', 'foreseen', 'deviations', 'library' (every "
                             "condition of "
                             "--library, or of the library's plan, as a damage nobody "
                             "foresaw, then the unforeseen cases it does not hold), "
                             "'second-tier' (the damages of the shipped priors' second "
                             "tier, their tables in), 'second-tier-pairs' (its pairs of "
                             'legs removed) or case names joined by ";"')
    parser.add_argument('--goals', default=None,
                        help='goals X,Y separated by spaces (default: (2,2) (-2,1.5) '
                             '(1.5,-2) (2.5,0.5))')
    parser.add_argument('--max-steps', type=int, default=60)
    parser.add_argument('--noise-std', type=float, default=0.01,
                        help="observation noise (m; the campaigns' 0.01)")
    parser.add_argument('--lookahead', type=float, default=None,
                        help="waypoint distance (m; default: the node's)")
    parser.add_argument('--out', default=None, help='JSON lines of every run (resumed)')
    parser.add_argument('--markdown', default=None, help='write the tables here')
    parser.add_argument('--figure', default=None,
                        help="draw every condition's ratios to the oracle here (PNG)")
    parser.add_argument('--library', default=None,
                        help='a damage library (scripts/build_library.py --assemble) for the '
                             'methods ' + ', '.join(LIBRARY_METHODS + BOUND_METHODS))
    parser.add_argument('--trace', action='store_true',
                        help="keep each SELA step's record in --out (scripts/step_budget.py "
                             'reads them)')
    parser.add_argument('--report-only', action='store_true',
                        help='run nothing: print the tables of the runs in --out')
    args = parser.parse_args(argv)
    from sela_ros.core.learning import resolve_priors
    from sela_ros.core.storage import default_archive_path, load_archive

    methods = [m for m in args.methods.split(',') if m]
    unknown = set(methods) - set(METHODS) - (set(REPORTED_ONLY) if args.report_only else set())
    if unknown:
        parser.error(f'unknown methods {sorted(unknown)}; expected some of {sorted(METHODS)}')
    if args.cases == 'library':
        cases = library_cases(args.library)
    elif args.cases == 'all':
        cases = UNFORESEEN + FORESEEN
    elif args.cases == 'deviations':
        cases = DEVIATIONS
    elif args.cases in ('unforeseen', 'foreseen'):
        cases = UNFORESEEN if args.cases == 'unforeseen' else FORESEEN
    elif args.cases == 'second-tier':
        cases = second_tier_cases()
    elif args.cases == 'second-tier-pairs':
        cases = tuple(c for c in second_tier_cases() if c[1].count('remove:') == 2)
    else:
        wanted = args.cases.split(';')
        known = UNFORESEEN + FORESEEN + DEVIATIONS + library_cases(args.library) \
            + second_tier_cases()
        by_label = {}
        for c in known:
            by_label.setdefault(c[0], c)
        cases = tuple(by_label[w] for w in dict.fromkeys(wanted) if w in by_label)
        if not cases:
            parser.error(f'no case named {wanted}')
    goals = GOALS if not args.goals else tuple(
        tuple(float(v) for v in g.split(',')) for g in args.goals.split())
    done = []
    if args.out and os.path.exists(args.out):
        with open(args.out) as handle:
            done = [json.loads(line) for line in handle if line.strip()]
    key = {(r['case'], tuple(r['goal']), r['method'], r['seed']) for r in done}
    if not args.report_only:
        archive = load_archive(default_archive_path())
        priors = resolve_priors('auto', default_archive_path(), archive.params)
        library = {}
        if set(methods) & set(BOUND_METHODS) and not args.library:
            parser.error(f'the methods {BOUND_METHODS} need --library')
        if set(methods) & set(LIBRARY_METHODS):
            if not args.library:
                parser.error(f'the methods {LIBRARY_METHODS} need --library')
            whole = resolve_priors(args.library, default_archive_path(), archive.params)
            library = library_priors(whole, cases, tempfile.mkdtemp(prefix='sela_library_'))
        if args.out:
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        # Seed by seed: an interrupted comparison has every cell at the same count.
        todo = [(c, g, m, s) for s in range(args.first_seed, args.seeds) for c in cases
                for g in goals
                for m in methods if (c[0], g, m, s) not in key]
        print(f'{len(todo)} runs to do ({len(done)} done already)', flush=True)
        shipped = tuple(priors.names) if priors is not None else ()
        for n, run in enumerate(_runs(todo, shipped, args, library), 1):
            if run is None:
                print(f'[{n}/{len(todo)}] nothing known of the damage\'s outcomes for the '
                      'oracle or a bound (the oracle\'s median comes from docs/results where '
                      'there is one)', flush=True)
                continue
            done.append(run)
            if args.out:
                with open(args.out, 'a') as handle:
                    handle.write(json.dumps(run) + '\n')
            print(f"[{n}/{len(todo)}] {run['case']} {tuple(run['goal'])} {run['method']} "
                  f"seed {run['seed']}: {'ok' if run['success'] else 'FAILED'} "
                  f"{run['steps']} steps, {run['falls']} falls, {run['wall_seconds']} s",
                  flush=True)
    names = {c[0] for c in cases}
    runs = [r for r in done if r['case'] in names and r['method'] in methods
            and tuple(r['goal']) in goals]
    # A whole table's oracle before one told only the library's gaits (oracle_check.md).
    oracle = {**measured_oracle(done, whole=False), **oracle_medians(),
              **measured_oracle(done, whole=True)}
    rows = summarise(runs, oracle, [m for m in methods if m != 'oracle'] or methods)
    shown = [m for m in methods if m not in ORACLE_METHODS] or methods
    text = (bar_table(runs, oracle, shown) + '\n\n' + totals(rows, runs, methods) + '\n\n'
            + paired(runs, methods) + '\n\n' + table(rows))
    if args.figure:
        figure(runs, oracle, shown, args.figure)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text + '\n')


if __name__ == '__main__':
    main()
