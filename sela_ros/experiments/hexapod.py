"""The paper's hexapod experiment: SELA, the IT&E baselines and the oracle, N replicates.

``sela-experiment hexapod --replicates 50 --damage remove:middle_right --goal 2,2 --out DIR``

Every replicate runs every method on its own simulated hexapod (PyBullet, in the worker
process), damaged from the start, standing at the origin. Within a replicate the robot is
never reset: learning trials (IT&E) move it too, and a fallen robot gets up where it lies
(the gait counts). Position observations carry Gaussian noise (``--noise-std``, default
0.01 m; the paper's sigma^2 = 0.01 read literally is 0.1 m). SELA runs the
``sela_adapter`` node's decision loop (:func:`~sela_ros.core.mission.run_mission`: its
stepper, damage detector and defaults) and, as the node, judges the goal on the observed
pose; the baselines judge it on the true pose (eps 0.1 m).

Choices the paper leaves open (see ``docs/hexapod_results.md`` for the measurements):

* Reward selection layer: the planner node's (an empty 8 m square centred on the start,
  :data:`~sela_ros.core.planning.DEFAULT_MAP`; a goal off it is refused) with a waypoint
  ``--lookahead`` metres along the path (default 0.6 m; the hexapod's gaits move 0-0.7 m
  per 3 s). With ``--map`` (a course name such
  as ``maze``, or a map YAML) the optimal grid path on that map, ``--inflation`` metres
  clear of obstacles (:class:`~sela_ros.core.planning.GridPlanner`); without ``--goal`` the
  run is the course's mission (its goals in order, learning carried over), and a gait that
  ends inside an obstacle counts as a collision (the simulator has no walls: the map is the
  planner's). See ``docs/course_results.md``.
* ``ite_4dir`` learns four targets in generic-reward space (dx, dy, dyaw): forward
  ``(max dx, 0, 0)``, backward ``(min dx, 0, 0)``, turn counter-clockwise
  ``(0, 0, max dyaw)`` and turn clockwise ``(0, 0, min dyaw)`` of the intact archive,
  15 M-BOA trials at most each; the task phase then picks, among the four learned
  gaits, the one predicted to land nearest the waypoint.
* The oracle knows every gait's outcome on the damaged robot from a standing start
  (:func:`sim_bridge.experiment_env.oracle_table`, cached on disk) and never picks a gait
  that falls there.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sela_ros.core.learning import SE2Motion, SELAConfig
from sela_ros.core.learning.self_model import SelfModelConfig
from sela_ros.core.planning import DEFAULT_INFLATION, PlanningError
from sela_ros.experiments import arguments
from sela_ros.experiments.baselines import METHODS, Problem
from sela_ros.experiments.workers import load_priors, worker_archive, worker_planner, worker_priors

HEXAPOD_METHODS = ('sela', 'ite_uncertainty', 'ite_4dir', 'oracle')
# Chosen by measurement (docs/hexapod_results.md): 0.5-1.0 m are alike, 0.4 m and below worse.
DEFAULT_LOOKAHEAD = SELAConfig.planner_lookahead
ITE_MAX_ITERATIONS = 15  # the paper's N for the hexapod
FALLEN_GR = 1e3  # the oracle's stand-in outcome for a gait that falls: never chosen


def archive_argument(text):
    from sela_ros.core.storage import ArchiveError, load_archive, resolve_archive_path
    from sim_bridge.settings import simulator_settings

    text = resolve_archive_path(text)
    try:
        archive = load_archive(text)
    except ArchiveError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    if archive.generic_reward.shape[1] != 3:
        raise argparse.ArgumentTypeError(f'{text}: generic rewards must be (dx, dy, dyaw)')
    settings = archive.simulator_settings
    try:
        simulator_settings(settings['dt'], settings['gait_duration'],
                           settings['solver_iterations'])
    except ValueError as err:
        raise argparse.ArgumentTypeError(f'{text}: {err}') from None
    return str(text)


def finish_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """After parsing: the robot, its archive and the damage in its names, checked together.

    ``args.robot`` becomes what finds the archive's robot in any process
    (:func:`sim_bridge.robots.robot_spec`), ``args.archive`` a path, ``args.damage`` the
    damage's canonical form."""
    from sela_ros.core.storage import load_archive
    from sim_bridge.damage import DamageSpecError
    from sim_bridge.robots import ROBOTS, get_robot, robot_of, robot_spec

    try:
        wanted = get_robot(args.robot) if args.robot is not None else None
    except ValueError as err:
        parser.error(f'--robot: {err}')
    if args.archive is None:
        described = wanted or get_robot(None)
        if not described.archive:
            parser.error(f'--archive: the {described.name} has no shipped map; build one '
                         '(docs/robots.md) and give it')
        try:
            args.archive = archive_argument(described.archive)
        except argparse.ArgumentTypeError as err:
            parser.error(f'--archive: {err}')
    robot = robot_of(load_archive(args.archive).metadata)
    if wanted is not None and wanted.name != robot:
        parser.error(f'--archive {args.archive} is a map of the {robot}, not of the '
                     f'{wanted.name}')
    try:
        description = wanted or get_robot(robot)
    except ValueError:
        parser.error(f'--archive {args.archive} is a map of the robot {robot!r}, which is not '
                     f'one of {", ".join(ROBOTS)}: give its description, --robot '
                     'package.module:DESCRIPTION (docs/robots.md)')
    args.robot = robot_spec(description)
    try:
        args.damage = description.parse_damage(
            description.default_damage if args.damage is None else args.damage).canonical()
    except DamageSpecError as err:
        parser.error(f'--damage: {err}')
    try:
        map_path, _, inflation, goal, via = mission(args)
        check_goals([*via, goal], map_path, inflation)
    except PlanningError as err:
        parser.error(str(err))
    check_oracle_cache(parser, args)


ORACLE_METHODS = ('oracle', 'oracle_2step')  # the methods that need the oracle's table


def cache_problem(directory):
    """Why the oracle's tables cannot be cached in ``directory`` (made if missing), or None."""
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        return 'is not a directory'
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        return f'cannot be made: {err.strerror or err}'
    try:
        with tempfile.TemporaryFile(dir=directory):
            pass
    except OSError as err:
        return f'cannot be written: {err.strerror or err}'
    return None


def check_oracle_cache(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """The oracle's cache directory, given or the default, checked (made if missing) before
    its table is computed: the table takes minutes, its cache must be able to keep it."""
    from sim_bridge.experiment_env import default_cache_dir

    if not args.oracle_cache and not set(ORACLE_METHODS) & set(args.methods):
        return
    where = args.oracle_cache or default_cache_dir()
    problem = cache_problem(where)
    if problem:
        named = ('--oracle-cache' if args.oracle_cache
                 else "the oracle's cache ($SELA_CACHE_DIR or ~/.cache/sela_ros/oracle)")
        parser.error(f'{named} {str(where)!r} {problem}')


def _course_map(text):
    """``--map``: a course name or a map file; returns ``(path, Course or None)``."""
    from sela_ros.core.planning import MapError, load_map_file
    from sela_ros.experiments.courses import find_course

    try:
        path, course = find_course(text)
        load_map_file(path)
    except (ValueError, MapError) as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return str(Path(path).resolve()), course


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``sela-experiment hexapod`` (the common ones are added by the CLI)."""
    from sim_bridge.robots import ROBOTS

    parser.add_argument('--robot', default=None,
                        help=f'the robot: {", ".join(ROBOTS)} or package.module:DESCRIPTION '
                             "(default: the archive's; the hexapod's shipped 8-D map when no "
                             '--archive is given)')
    parser.add_argument('--archive', type=archive_argument, default=None,
                        help='behaviour-performance map (.npz, or 8d / 2d / a1 for the shipped '
                             "ones; default: the robot's shipped map, for the hexapod the 8-D "
                             'one, sela_ros/data/hexapod_archive.npz)')
    parser.add_argument('--damage', default=None,
                        help="damage spec in the robot's names, e.g. remove:middle_right (the "
                             "hexapod's default, the paper's), shorten:front_left:0.5, "
                             "block:rear_right.knee=0.2 (default: the robot's, docs/robots.md)")
    parser.add_argument('--goal', type=arguments.goal, default=None,
                        help="goal X,Y in metres from the start (default 2,2; with --map: "
                             "the course's goals in order, a mission)")
    parser.add_argument('--map', type=_course_map, default=None,
                        help='plan on this map: a shipped course (wall_gap, corridor, maze) '
                             "or a map YAML (map_server's or the project's format)")
    parser.add_argument('--inflation', type=arguments.non_negative_float,
                        default=DEFAULT_INFLATION,
                        help='with --map: clearance kept from obstacles (m, default '
                             '%(default)s, as the planner node)')
    parser.add_argument('--noise-std', type=arguments.noise_std,
                        default=arguments.DEFAULT_NOISE_STD, help=arguments.NOISE_HELP)
    parser.add_argument('--lookahead', type=arguments.positive_float, default=DEFAULT_LOOKAHEAD,
                        help='reward selection layer: waypoint distance along the straight '
                             'path to the goal (m, default %(default)s)')
    parser.add_argument('--kernel-sigma', type=arguments.kernel_sigma, default=None,
                        help="gp.kernel.sigma on normalised descriptors (default: the "
                             "archive's: 0.1, the paper's, for the 2-D map; 0.3 for the 8-D "
                             "map)")
    parser.add_argument('--fall-cost', type=arguments.non_negative_float, default=None,
                        help="fall.risk.cost: metres of progress a fall is worth in SELA's "
                             'choice (default: SELA\'s default)')
    parser.add_argument('--fall-kernel-sigma', type=arguments.kernel_sigma, default=None,
                        help="fall.kernel.sigma: kernel length of the fall GP (default: the "
                             "archive's: 0.1 on a 2-D map, 0.12 on the 8-D map)")
    parser.add_argument('--alpha', type=arguments.non_negative_float,
                        default=SELAConfig().acquisition_ucb_alpha,
                        help="acquisition.ucb.alpha (default %(default)s, the paper's)")
    parser.add_argument('--fall-risk', type=arguments.positive_float,
                        default=SELAConfig().fall_risk_threshold,
                        help='fall.risk.threshold: SELA avoids gaits predicted to fall with '
                             'a higher risk (default %(default)s; 1 or more: no avoidance)')
    parser.add_argument('--methods', type=arguments.method_list, default=list(HEXAPOD_METHODS),
                        help='comma-separated methods (default: %(default)s; also '
                             'random_babbling)')
    parser.add_argument('--max-steps', type=arguments.positive_int, default=100,
                        help='task-step cap; a run that hits it fails (default %(default)s)')
    parser.add_argument('--ite-iterations', type=arguments.positive_int,
                        default=ITE_MAX_ITERATIONS,
                        help="IT&E trials (ite_uncertainty) and M-BOA trials per direction "
                             "(ite_4dir) at most (default %(default)s, the paper's N)")
    add_priors_arguments(parser)
    parser.add_argument('--oracle-cache', default=None,
                        help='directory of cached oracle tables (default $SELA_CACHE_DIR or '
                             '~/.cache/sela_ros/oracle)')


def add_priors_arguments(parser: argparse.ArgumentParser) -> None:
    """``--priors``, ``--priors-leave-out-own`` and ``--horizon`` (hexapod and campaign)."""
    parser.add_argument('--horizon', type=int, choices=(1, 2), default=None,
                        help="planner.horizon of SELA: steps looked ahead (default: the "
                             "archive's: 1, the paper's, on the 2-D map, 2 on the 8-D map)")
    parser.add_argument('--priors', default='auto',
                        help="SELA's damage priors (docs/archive.md): auto (default) = those "
                             "shipped beside the archive if any, none = the intact map only "
                             "(the paper's SELA), or a path to a priors .npz")
    parser.add_argument('--priors-leave-out-own', action='store_true',
                        help="drop the run's own damage from the damage priors, as if "
                             'nobody had foreseen it')
    parser.add_argument('--self-model-gaits', type=arguments.non_negative_int,
                        default=SelfModelConfig.gaits,
                        help="SELA's self-model (the sela_adapter's self_model.*): gaits "
                             'simulated for the damage the feet show, its table in use '
                             f'{SelfModelConfig.delay_steps} steps later; 0: no self-model '
                             '(default %(default)s)')
    parser.add_argument('--self-model-refine', type=arguments.non_negative_int,
                        default=SelfModelConfig.refine,
                        help='gaits the self-model simulates next once its table is in use, '
                             'those it infers go farthest (self_model.refine; in use in '
                             'proportion later; default %(default)s)')


def self_model_argument(args):
    """The runs' self-model settings from ``--self-model-gaits`` (0: none) and
    ``--self-model-refine``."""
    gaits = getattr(args, 'self_model_gaits', SelfModelConfig.gaits)
    refine = getattr(args, 'self_model_refine', SelfModelConfig.refine)
    return SelfModelConfig(gaits=gaits, covering=gaits // 2, refine=refine) if gaits else None


def ite_targets(prior_gr) -> np.ndarray:
    """Forward, backward, turn ccw, turn cw targets (dx, dy, dyaw) from the intact map."""
    prior_gr = np.asarray(prior_gr, dtype=float)
    return np.array([[prior_gr[:, 0].max(), 0.0, 0.0],
                     [prior_gr[:, 0].min(), 0.0, 0.0],
                     [0.0, 0.0, prior_gr[:, 2].max()],
                     [0.0, 0.0, prior_gr[:, 2].min()]])


#: SELA parameters a results.json records (resolved: the archive's own where left out).
RECORDED_SELA_PARAMETERS = ('gp.kernel.sigma', 'acquisition.ucb.alpha', 'fall.risk.threshold',
                            'fall.kernel.sigma', 'fall.risk.cost', 'priors.max.misfit',
                            'priors.max.misfit.reproduced', 'planner.horizon')


def sela_config(archive, lookahead, kernel_sigma=None, alpha=None, fall_risk=None,
                fall_kernel_sigma=None, fall_cost=None, horizon=None,
                weights_sd=None, caution=None, mean_affine=None,
                progress=None, mean_affine_descriptor=None, reach=None,
                hyper_sd=None, reach_chance=None) -> SELAConfig:
    """The SELA parameters of a run: those given, the archive's own for the rest."""
    from sela_ros.core.mission import archive_config

    given = {'planner.lookahead': lookahead, 'fall.risk.threshold': fall_risk or None,
             'gp.kernel.sigma': kernel_sigma, 'fall.kernel.sigma': fall_kernel_sigma,
             'fall.risk.cost': fall_cost, 'acquisition.ucb.alpha': alpha,
             'planner.horizon': horizon, 'priors.weights.sd': weights_sd,
             'acquisition.caution': caution, 'gp.mean.affine': mean_affine,
             'acquisition.progress': progress,
             'gp.mean.descriptor': mean_affine_descriptor, 'planner.reach': reach,
             'gp.hyper.sd': hyper_sd,
             'acquisition.reach': reach_chance}
    return archive_config(archive, {k: v for k, v in given.items() if v is not None})


def make_problem(archive, goal, lookahead, max_steps, true_gr=None,
                 ite_iterations=ITE_MAX_ITERATIONS, kernel_sigma=None, alpha=None,
                 fall_risk=None, planner=None, via=(), fall_kernel_sigma=None,
                 fall_cost=None, priors=None, horizon=None, weights_sd=None,
                 caution=None, mean_affine=None, progress=None,
                 mean_affine_descriptor=None, reach=None, hyper_sd=None,
                 reach_chance=None) -> Problem:
    config = sela_config(archive, lookahead, kernel_sigma, alpha, fall_risk,
                         fall_kernel_sigma, fall_cost, horizon, weights_sd, caution,
                         mean_affine, progress, mean_affine_descriptor, reach, hyper_sd,
                         reach_chance)
    return Problem(
        candidates=archive.normalised_descriptors(),
        prior_gr=archive.generic_reward,
        motion=SE2Motion(),
        goal=np.asarray(goal, dtype=float),
        via=tuple(via),
        planner=planner,
        config=config,
        max_steps=max_steps,
        true_gr=true_gr,
        ite_targets=ite_targets(archive.generic_reward),
        ite_max_iterations=ite_iterations,
        uncertainty_iterations=ite_iterations,
        babbling_max_iterations=ite_iterations,
        stability=archive.stability,
        priors=priors,
    )


#: Errors that are the user's: said as a usage error (sela-experiment).
ARGUMENT_ERRORS = (PlanningError,)


#: Where every run starts (x, y): the origin of the map.
START = (0.0, 0.0)


def check_goals(goals, map_path, inflation, start=START, hint=None):
    """Refuse a mission the planner could not plan, before anything runs: a start or a goal
    off the map or inside an obstacle (as the nodes refuse a goal), or a goal with no path
    to it from the start (through the goals before it) ``inflation`` metres clear of
    obstacles. Raises :class:`PlanningError` saying which; ``hint`` says what to do about
    a goal the planner refuses (default: about ``--map``)."""
    grid, planner = worker_planner(map_path, inflation)
    on = f'the map {map_path}' if map_path else "the planner's default map"
    if hint is None:
        hint = ('give another --map, or goals on it' if map_path
                else 'give a map that holds it: --map')
    problem = grid.goal_problem(start)
    if problem:
        raise PlanningError(f'the start ({start[0]:g}, {start[1]:g}), where every run begins, '
                            f'is {problem} on {on}: give a map on which it is free')
    for goal in goals:
        problem = grid.goal_problem(goal)
        if problem:
            raise PlanningError(f'goal ({goal[0]:g}, {goal[1]:g}) is {problem}: the planner '
                                f'refuses it ({hint})')
    previous, origin = start, 'the start'
    for goal in goals:
        try:
            planner(previous, goal)
        except PlanningError as err:
            raise PlanningError(f'goal ({goal[0]:g}, {goal[1]:g}) cannot be reached from '
                                f'{origin} ({previous[0]:g}, {previous[1]:g}) on {on} with '
                                f'--inflation {inflation:g} m: {err}') from None
        previous, origin = goal, 'the goal before it'


@dataclass(frozen=True)
class Job:
    """One method on one replicate (what a worker process is given).

    ``seed`` (a ``numpy.random.SeedSequence``) seeds the observation noise and the method;
    ``noise_seed``, when given, seeds the observation noise as the ``sim_bridge`` node's
    ``seed`` parameter does (so that a replicate and a ``sela-demo --seed`` run observe the
    same noise). The rest are the experiment's options (see :func:`add_arguments`)."""

    name: str
    seed: object
    archive: str
    damage: str
    goal: tuple
    noise_std: float = arguments.DEFAULT_NOISE_STD
    lookahead: float = DEFAULT_LOOKAHEAD
    max_steps: int = 100
    ite_iterations: int = ITE_MAX_ITERATIONS
    oracle_gr: object = None
    kernel_sigma: float = None
    alpha: float = None
    fall_risk: float = None
    map_path: str = None
    inflation: float = DEFAULT_INFLATION
    via: tuple = ()
    fall_kernel_sigma: float = None
    fall_cost: float = None
    priors: str = 'auto'
    leave_out_own: bool = False
    horizon: float = None
    noise_seed: int = None
    weights_sd: object = None  # priors.weights.sd (None: the default)
    caution: object = None  # acquisition.caution, m or 'none' (None: the default)
    mean_affine: object = None  # gp.mean.affine, or 'none' (None: the default)
    progress: object = None  # acquisition.progress, or 'none' (None: the default)
    mean_affine_descriptor: object = None  # gp.mean.descriptor (None: the default)
    reach: object = None  # planner.reach, or 'none' (None: the default)
    hyper_sd: object = None  # gp.hyper.sd, or 'none' (None: the default)
    reach_chance: object = None  # acquisition.reach, m or 'none' (None: the default)
    trace: bool = False  # keep each step's record in the output ('steps_detail')
    # (M, 3) the GPs' prior mean in place of the map's (None: the map's): what SELA does with
    # a given table as its prior, for bounds (scripts/compare_priors.py, bound-own, bound-fit)
    prior_mean: object = None
    robot: str = None  # what finds the robot in a worker (None: the archive's, by its name)
    # the self-model's settings (sela_ros.core.learning.self_model.SelfModelConfig; None: none):
    # the sela_adapter node's defaults
    self_model: object = SelfModelConfig()


class _OracleProgress:
    """The oracle's table, when it is simulated (not cached): a line that says so, then a
    bar of the gaits done on stderr (none with ``--quiet``)."""

    def __init__(self, gaits, damage, workers, quiet):
        self.gaits, self.damage, self.workers, self.quiet = gaits, damage, workers, quiet
        self.bar = None

    def __enter__(self):
        return self

    def update(self, count):
        if self.quiet:
            return
        if self.bar is None:
            from tqdm import tqdm

            tqdm.write(f"the oracle's table of '{self.damage}' is not cached: simulating all "
                       f'{self.gaits:,} gaits of the map on {self.workers} worker(s) '
                       '(--workers; once per damage, then cached: --oracle-cache)',
                       file=sys.stderr)
            self.bar = tqdm(total=self.gaits, desc='oracle table', unit='gait',
                            file=sys.stderr, position=1, leave=False)
        self.bar.update(count)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()


def run_method(job: Job):
    """One method on one replicate; returns a dict of plain numbers."""
    from sela_ros.experiments.courses import CourseEnvironment
    from sim_bridge.experiment_env import RobotEnvironment
    from sim_bridge.robots import robot_of

    archive = worker_archive(job.archive)
    # The planner node's map, or the course's: the nodes and the experiments plan alike.
    grid, planner = worker_planner(job.map_path, job.inflation)
    if not job.map_path:
        grid = None  # no course: no collisions or paths to count
    settings = archive.simulator_settings
    env_seed, method_seed = job.seed.spawn(2)
    noise = job.noise_seed if job.noise_seed is not None else np.random.default_rng(env_seed)
    start = time.perf_counter()
    with RobotEnvironment(archive.params, job.damage, noise_std=job.noise_std, seed=noise,
                          dt=settings['dt'], gait_duration=settings['gait_duration'],
                          solver_iterations=settings['solver_iterations'],
                          robot=job.robot or robot_of(archive.metadata)) as sim:
        env = CourseEnvironment(sim, grid) if grid is not None else sim
        problem = make_problem(archive, job.goal, job.lookahead, job.max_steps,
                               true_gr=job.oracle_gr, ite_iterations=job.ite_iterations,
                               kernel_sigma=job.kernel_sigma, alpha=job.alpha,
                               fall_risk=job.fall_risk, planner=planner, via=job.via,
                               fall_kernel_sigma=job.fall_kernel_sigma,
                               fall_cost=job.fall_cost,
                               priors=worker_priors(job.priors, job.archive, job.damage,
                                                    job.leave_out_own),
                               horizon=job.horizon, weights_sd=job.weights_sd,
                               caution=job.caution, mean_affine=job.mean_affine,
                               progress=job.progress,
                               mean_affine_descriptor=job.mean_affine_descriptor,
                               reach=job.reach, hyper_sd=job.hyper_sd,
                               reach_chance=job.reach_chance)
        if job.prior_mean is not None:
            problem = dataclasses.replace(problem,
                                          prior_gr=np.asarray(job.prior_mean, dtype=float))
        if job.self_model is not None and job.name == 'sela':
            problem = dataclasses.replace(problem, self_model=make_self_model(
                archive, sim.robot.description, job.self_model))
        result = METHODS[job.name](env, problem, np.random.default_rng(method_seed))
        final = env.true_pose()
        out = {'success': bool(result.success), 'steps': int(result.steps),
               'learning_iterations': int(result.learning_iterations),
               'behaviors': [int(i) for i in result.behaviors],
               'falls': int(sim.falls), 'sim_seconds': sim.sim_seconds,
               'wall_seconds': time.perf_counter() - start,
               'final_distance': float(np.hypot(final[0] - job.goal[0],
                                                final[1] - job.goal[1]))}
        if job.trace:
            out['steps_detail'] = [step_detail(r) for r in result.records]
        if grid is not None:
            out.update(collisions=int(env.collisions), path=env.path,
                       goal_steps=list(result.goal_steps))
        return out


def make_self_model(archive, robot, config):
    """``(SelfModel, simulate)``: a :class:`~sela_ros.core.learning.self_model.SelfModel` of
    ``robot`` (a description) over ``archive``, and its hypotheses' simulator, as the damage
    library's gaits are simulated (:func:`sim_bridge.evaluation.simulate_gaits`, here); None
    for a map whose descriptor holds no duty factors."""
    from sela_ros.core.learning.self_model import from_archive
    from sim_bridge.evaluation import simulate_gaits

    def simulate(damage, gaits):
        return simulate_gaits(archive.params[gaits], damage, archive.simulator_settings, robot)

    try:
        return from_archive(archive, robot.legs, config, robot.vocabulary.kinds), simulate
    except ValueError:  # a map with no duty factors (2-D): no feet to read
        return None


def step_detail(record) -> dict:
    """A step's record (``StepRecord``) as a mission's summary keeps it, numbers rounded."""
    out = {}
    for key, value in record.to_dict().items():
        if isinstance(value, (list, tuple)):
            value = [round(float(v), 4) for v in value]
        elif isinstance(value, float):
            value = round(value, 4)
        out[key] = value
    return out


def mission(args):
    """``(map path, Course, inflation, goal, via)`` of a run: on a course without ``--goal``
    the course's mission, its goals in order (``via`` those before the last); else the goal
    alone (default 2, 2)."""
    # Callers that build args by hand (the campaign) may leave out the map options.
    map_path, course = getattr(args, 'map', None) or (None, None)
    inflation = getattr(args, 'inflation', DEFAULT_INFLATION)
    goal = args.goal or (list(course.goals[-1]) if course else [2.0, 2.0])
    via = [list(g) for g in course.goals[:-1]] if course and not args.goal else []
    return map_path, course, inflation, goal, via


def run(args, progress=None) -> dict:
    """Run the experiment described by ``args``; returns the results.json document."""
    from sela_ros.core.storage import load_archive
    from sim_bridge.evaluation import worker_pool
    from sim_bridge.experiment_env import archive_checksum, oracle_table
    from sim_bridge.robots import get_robot, robot_of

    archive = load_archive(args.archive)
    robot = getattr(args, 'robot', None) or robot_of(archive.metadata)
    settings = archive.simulator_settings
    map_path, course, inflation, goal, via = mission(args)
    check_goals([*via, goal], map_path, inflation)
    # The parameters every run uses (the archive's own where left out), for the record.
    priors_value = getattr(args, 'priors', 'auto')
    leave_out_own = bool(getattr(args, 'priors_leave_out_own', False))
    priors = load_priors(priors_value, args.archive, archive, args.damage, leave_out_own)
    oracle_gr = None
    oracle_seconds = 0.0
    oracle_falls = 0
    if set(ORACLE_METHODS) & set(args.methods):
        start = time.perf_counter()
        with _OracleProgress(len(archive.params), args.damage, args.workers,
                             getattr(args, 'quiet', False)) as shown:
            gr, fallen = oracle_table(archive.params, args.damage, workers=args.workers,
                                      cache_dir=args.oracle_cache, dt=settings['dt'],
                                      gait_duration=settings['gait_duration'],
                                      solver_iterations=settings['solver_iterations'],
                                      robot=robot, progress=shown.update)
        oracle_seconds = time.perf_counter() - start
        oracle_gr = np.where(fallen[:, None], FALLEN_GR, gr)
        oracle_falls = int(fallen.sum())
    used = sela_config(archive, args.lookahead, kernel_sigma=args.kernel_sigma,
                       alpha=args.alpha, fall_risk=args.fall_risk,
                       fall_kernel_sigma=getattr(args, 'fall_kernel_sigma', None),
                       fall_cost=getattr(args, 'fall_cost', None),
                       horizon=getattr(args, 'horizon', None)).to_dict()
    seeds = np.random.SeedSequence(args.seed).spawn(args.replicates)
    # Each method's seeds are its slot in the full list of methods: run on their own later
    # (the campaign adding a method to a cell), they are those of a run of all of them.
    slots = list(getattr(args, 'method_slots', None) or args.methods)
    jobs = []
    for seed in seeds:
        children = seed.spawn(len(slots))
        for name in args.methods:
            child = children[slots.index(name)]
            jobs.append(Job(name, child, os.path.abspath(args.archive), args.damage,
                            tuple(goal), args.noise_std, args.lookahead, args.max_steps,
                            args.ite_iterations, oracle_gr, args.kernel_sigma, args.alpha,
                            args.fall_risk, map_path, inflation, tuple(map(tuple, via)),
                            getattr(args, 'fall_kernel_sigma', None),
                            getattr(args, 'fall_cost', None), priors_value, leave_out_own,
                            getattr(args, 'horizon', None), robot=robot,
                            self_model=self_model_argument(args)))
    per_rep = len(args.methods)
    results = []
    start = time.perf_counter()
    if args.workers <= 1:
        for i, job in enumerate(jobs):
            results.append(run_method(job))
            if progress and (i + 1) % per_rep == 0:
                progress()
    else:
        # Jobs are (replicate, method) pairs in replicate order, so progress is in order too.
        with worker_pool(args.workers) as pool:
            for i, r in enumerate(pool.map(run_method, jobs)):
                results.append(r)
                if progress and (i + 1) % per_rep == 0:
                    progress()
    wall = time.perf_counter() - start
    methods = {}
    timing = {}
    for k, name in enumerate(args.methods):
        runs = results[k::per_rep]
        methods[name] = {
            'success': [r['success'] for r in runs],
            'steps': [r['steps'] for r in runs],
            'learning_iterations': [r['learning_iterations'] for r in runs],
            'falls': [r['falls'] for r in runs],
            'final_distance': [round(r['final_distance'], 4) for r in runs],
        }
        if map_path:
            methods[name]['collisions'] = [r['collisions'] for r in runs]
            methods[name]['paths'] = [r['path'] for r in runs]
            methods[name]['goal_steps'] = [r['goal_steps'] for r in runs]
        timing[name] = {'sim_seconds': float(sum(r['sim_seconds'] for r in runs)),
                        'wall_seconds': float(sum(r['wall_seconds'] for r in runs))}
    summary = {name: {'successes': int(sum(m['success'])),
                      'median_steps': float(np.median(m['steps'])),
                      'median_learning_iterations': float(np.median(m['learning_iterations'])),
                      'median_total': float(np.median(np.add(m['steps'],
                                                             m['learning_iterations']))),
                      'falls': int(sum(m['falls']))}
               for name, m in methods.items()}
    if map_path:
        for name, m in methods.items():
            summary[name]['collisions'] = int(sum(m['collisions']))
            summary[name]['runs_with_collisions'] = int(sum(c > 0 for c in m['collisions']))
    return {'scenario': 'hexapod', 'replicates': args.replicates, 'methods': methods,
            'seed': args.seed,
            'parameters': {'robot': get_robot(robot).name, 'noise_std': args.noise_std,
                           'max_steps': args.max_steps,
                           'damage': args.damage, 'goal': list(goal), 'via': via,
                           'start': [0.0, 0.0, 0.0], 'lookahead': args.lookahead,
                           'planner': 'grid',
                           'map': map_path, 'course': course.name if course else None,
                           'inflation': inflation if map_path else None,
                           'goal_eps': SELAConfig().goal_eps,
                           'ite_max_iterations': args.ite_iterations,
                           **{k: used[k] for k in RECORDED_SELA_PARAMETERS},
                           'archive': os.path.abspath(args.archive),
                           'archive_checksum': archive_checksum(archive.params),
                           'damage_priors': None if priors is None else list(priors.names),
                           'num_behaviours': len(archive),
                           'oracle_gaits_that_fall': oracle_falls},
            'timing': {'wall_seconds': wall, 'workers': args.workers,
                       'oracle_table_seconds': oracle_seconds, 'methods': timing},
            'summary': summary}


def write_figures(doc, out) -> list:
    """With ``--map``: ``paths.png``, every replicate's path drawn over the course."""
    params = doc['parameters']
    if not params.get('map'):
        return []
    from sela_ros.core.planning import load_map_file
    from sela_ros.experiments.figures import plot_course_paths

    path = os.path.join(out, 'paths.png')
    plot_course_paths(doc, load_map_file(params['map']), path)
    return [path]
