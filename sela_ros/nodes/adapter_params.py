"""The ``sela_adapter`` node's parameters: names, defaults, descriptions, ranges, and what
they configure (SELA and the mission stepper). Declared through :func:`params.declare`."""
from sela_ros.core.learning import AUTO, NONE, SELAConfig, gp
from sela_ros.core.learning.self_model import SelfModelConfig
from sela_ros.core.mission import ON_DETECTION, StepperConfig
from sela_ros.core.storage import persistence
from sela_ros.core.validation import archive_displacement_limit
from sela_ros.nodes import interface as ifc
from sela_ros.nodes.params import Spec

PARAMETERS = (
    Spec('archive', '', "the MAP-Elites archive (.npz); '' = the one shipped with the package "
         "(the 8-D map), '8d' / '2d' = the shipped ones by name; can change between steps, to "
         "one built for the simulator's physics (sim_bridge's archive)"),
    Spec('gp.kernel.sigma', AUTO, "kernel length on normalised descriptors; auto = the "
         "archive's (0.1, the paper's, for a 2-D map; 0.3 for the 8-D map)", low=gp.MIN_SIGMA,
         high=gp.MAX_SIGMA, kind='double', word=AUTO, read_only=True),
    Spec('gp.noise', 0.001, 'GP noise variance', low=0.0, high=100.0, read_only=True),
    Spec('gp.hyper.sd', NONE if SELAConfig.gp_hyper_sd is None
         else SELAConfig.gp_hyper_sd, 'prior standard deviation of the logs of the GP kernel '
         'length and signal variance learnt from the steps (marginal likelihood of their '
         'residuals), centred on gp.kernel.sigma and its variance; none = fixed (the '
         "paper's)", low=0.0, high=100.0, kind='double', word=NONE, read_only=True),
    Spec('gp.mean.affine', NONE if SELAConfig.gp_mean_affine is None
         else SELAConfig.gp_mean_affine, 'prior standard deviation of the '
         'scale and rotation of an affine map of the prior mean learnt from the steps (what '
         "the damage does to every gait), centred on the identity; none = the prior mean as "
         "it is (the paper's)", low=0.0, high=100.0, kind='double', word=NONE,
         read_only=True),
    Spec('gp.mean.descriptor', NONE if SELAConfig.gp_mean_descriptor is None
         else SELAConfig.gp_mean_descriptor, 'prior standard deviation of the terms '
         "of that affine map's scale linear in the gait's descriptor (a leg lost slows the "
         'gaits that lean on it most), centred on zero; used with gp.mean.affine; none = one '
         'scale for the whole map', low=0.0, high=100.0, kind='double', word=NONE,
         read_only=True),
    Spec('acquisition.ucb.alpha', 0.05, 'UCB exploration weight', low=0.0, high=100.0,
         read_only=True),
    Spec('acquisition.caution', SELAConfig.acquisition_caution, 'once untried gaits land '
         'this far from their predictions (rms per axis, learnt from the steps), each gait '
         'is scored by its expected distance to the waypoint, which prefers gaits already '
         "tried; none = never (the paper's: the predicted distance)", low=0.0, high=100.0,
         unit=' m', kind='double', word=NONE, read_only=True),
    Spec('acquisition.progress', NONE if SELAConfig.acquisition_progress is None
         else SELAConfig.acquisition_progress, 'each gait is scored by how far along the '
         'planned path (past the waypoint, to the goal) its predicted landing puts the robot, '
         "less this weight times its distance off the path; none = by its distance to the "
         "waypoint (the paper's)", low=0.0, high=100.0, kind='double', word=NONE,
         read_only=True),
    Spec('acquisition.reach', NONE if SELAConfig.acquisition_reach is None
         else SELAConfig.acquisition_reach, 'while caution is on, each gait is scored by the '
         'probability that its landing falls within this distance of the waypoint (two steps '
         "ahead: of both); none = caution's expected distance", low=0.0, high=100.0,
         unit=' m', kind='double', word=NONE, read_only=True),
    Spec('goal.eps', 0.1, 'the goal is reached within this distance', low=1e-4, high=100.0,
         unit=' m', read_only=True),
    Spec('fall.risk.threshold', 0.3, 'risk of falling accepted: gaits predicted riskier are '
         'not tried (1: no avoidance)', low=0.0, high=1.0, read_only=True),
    Spec('fall.risk.cost', 1.0, 'what a fall costs, in metres of predicted progress: UCB takes '
         'cost x risk off every gait (0: only the threshold)', low=0.0, high=100.0,
         unit=' m', read_only=True),
    Spec('fall.kernel.sigma', AUTO, "kernel length of the fall GP; auto = the archive's (0.1 "
         'for a 2-D map, 0.12 for the 8-D map)', low=gp.MIN_SIGMA, high=gp.MAX_SIGMA,
         kind='double', word=AUTO, read_only=True),
    Spec('planner.lookahead', SELAConfig.planner_lookahead, 'distance along the path to the '
         'waypoint of the reward', low=0.01, high=100.0, unit=' m', read_only=True),
    Spec('planner.reach', NONE if SELAConfig.planner_reach is None
         else SELAConfig.planner_reach, "the waypoint is set at this multiple of the robot's "
         'shown reach (the 0.9 quantile of the planar displacements of the steps learnt that '
         'stayed up, once 3 are), within [0.15 m, planner.lookahead]; none = planner.lookahead '
         "(the paper's)", low=0.0, high=100.0, kind='double', word=NONE, read_only=True),
    Spec('planner.horizon', AUTO, "steps looked ahead: 1 = the paper's (the gait landing "
         'nearest the waypoint), 2 = the gait that leaves the robot best placed for the next '
         "one; auto = the archive's (1 for a 2-D map, 2 for the 8-D map)", low=1, high=2,
         kind='integer', word=AUTO, read_only=True),
    Spec('priors.tables', 'auto', "damage priors: tables of the archive's gaits on foreseen "
         "damages (docs/archive.md); 'auto' = those shipped beside the archive if any, "
         "'library' = the damage library beside it (90 conditions, docs/damage_library.md), "
         "'none' = the intact map only (the paper), or a path (.npz from `make priors`)",
         read_only=True, renamed_from='priors'),
    Spec('priors.max_misfit', SELAConfig.priors_max_misfit, 'a damage prior is used on its '
         'own only while its median squared error over the steps seen is below this (units '
         'of 0.1 m, 0.1 m, 0.25 rad); none = never (the tables serve only in the mixture)',
         low=0.0, high=1e6, word=NONE, read_only=True, renamed_from='priors.max.misfit'),
    Spec('priors.max_misfit_reproduced', 2.0, 'the same cap for a damage prior that '
         'reproduced the steps from a standing start (spawned, reset or righted: a third of '
         'them or more); below priors.max_misfit = no exception', low=0.0, high=1e6,
         read_only=True,
         renamed_from='priors.max.misfit.reproduced'),
    Spec('priors.weights.sd', SELAConfig.priors_weights_sd, 'while no damage prior '
         'reproduced the steps from a standing start, the prior mean is the tables mixed by '
         'weights fitted to the steps seen (docs/priors_combination.md); this is the prior '
         'spread of each weight; none = no mixture, the one table that best explains the '
         'steps', low=0.0, high=1e6, word=NONE, read_only=True),
    Spec('self_model.enabled', True, "read the robot's feet (each outcome's duty factors): "
         'legs whose feet never touch the ground, over two steps or more whose gaits lean on '
         "them, are a damage that the robot's simulator (sim_bridge) plays beside the "
         'mission on self_model.gaits gaits (a leg the others tilt off the ground is told '
         'apart first), and its table is a damage prior (docs/learning_the_damage.md); '
         'needs a map with duty factors (the 8-D map)', read_only=True),
    Spec('self_model.gaits', SelfModelConfig.gaits, 'gaits of the map simulated for a '
         'damage the feet show (the gaits the robot ran besides), the others inferred; each '
         'costs one simulated gait (about 0.05 s of a core on the hexapod: 600 take 15 s on '
         'two workers)', low=1,
         high=10**6, read_only=True),
    Spec('self_model.refine', SelfModelConfig.refine, 'once its table is in use, gaits '
         'simulated next for the damage: those its inferred part says go farthest, the best '
         'of every direction of travel (an inferred gait is never chosen); 0 = none',
         low=0, high=10**6, read_only=True),
    Spec('self_model.workers', 2, 'processes that simulate beside the mission, sharing each '
         "damage's gaits (started at the first damage the feet show)", low=1, high=256,
         read_only=True),
    Spec('max_steps', StepperConfig.max_steps, 'steps before a mission is declared failed',
         low=1, high=10**9),
    Spec('max_waypoints', 1000, 'goals in one mission at most (goal_path poses, or '
         "follow_waypoints' poses times its loops): a longer one is refused", low=1,
         high=10**6),
    Spec('detector_timeout', StepperConfig.detector_timeout, "wall time to wait for the "
         "detector's verdict on an outcome", low=0.001, high=3600.0, unit=' s'),
    Spec('outcome_timeout', StepperConfig.outcome_timeout, 'wall time to wait for the '
         'outcome of a command before sending it again', low=0.001, high=3600.0, unit=' s'),
    Spec('outcome_attempts', StepperConfig.outcome_attempts, 'sends of one command with no '
         'outcome before the mission fails (the simulator or the robot does not answer)',
         low=1, high=1000),
    Spec('outcome.max_refused', StepperConfig.max_refused_steps, 'steps in a row whose outcome '
         'is refused (implausible, or from elsewhere than the pose the step was planned from) '
         'before the mission fails; each is followed by a fresh plan from where odometry '
         'puts the robot', low=1, high=1000),
    Spec('adapt_on_start', StepperConfig.adapt_on_start, 'learn from the first step (false: '
         'trust the map until the damage detector fires)', read_only=True),
    Spec('frame_id', 'odom', 'frame of goals, poses and plans', read_only=True),
    Spec('map_frame', 'map', "a frame taken as frame_id: goals in it are used as given in "
         'frame_id (no localisation here: the odometry is the map, as in the simulator or '
         "with motion capture; '' = refused)", read_only=True),
    Spec('state_file', '', "where learning is saved after every step ('' = "
         '~/.ros/sela_ros/[<namespace>/]sela_adapter_state.json); a regular file or none yet '
         '(a symbolic link is written through), one adapter\'s alone (a second adapter given '
         'it neither resumes from it nor saves to it)', read_only=True,
         rule=lambda value: persistence.path_problem(value) if value else None),
    Spec('max_observations', StepperConfig.max_observations, 'observations (generic '
         'rewards, falls) learning keeps over the robot\'s life, the latest: bounds the state '
         'file, its start-up time and the memory (a tenth more before the oldest are '
         'forgotten)', low=10, high=100000),
    Spec('resume', True, 'read the state file at start-up (lifelong learning)', read_only=True),
    Spec('reset_on_fall', StepperConfig.reset_on_fall, 'true: after a step that ends fallen, '
         'call sim_bridge/reset and go on from the start (episodic set-ups); false: go on '
         'from where the robot got up', read_only=True),
    Spec('adaptation.on_detection', StepperConfig.on_detection, 'a new detection while '
         "adapting: keep what was learned ('keep'), restart from the latest step ('reset'), "
         "or restart only when several learnt gaits land far from what they did "
         "('evidence'); a restart sets what it replaces aside in the state file",
         rule=lambda v: None if v in ON_DETECTION else f'must be one of {ON_DETECTION}',
         read_only=True),
    Spec('outcome.max_displacement', AUTO, 'an outcome that moves the robot further than this '
         "in one gait is refused, never learnt; auto = twice the archive's furthest gait "
         '(1.25 m on the shipped 8-D map)', low=1e-3, high=1e6, unit=' m', kind='double',
         word=AUTO),
    Spec('simulator_node', ifc.SIM_BRIDGE, "whose sim.dt, sim.gait_duration and "
         "sim.solver_iterations the archive must match ('' on a real robot: no check)",
         read_only=True),
)
SELA_KEYS = ('gp.kernel.sigma', 'gp.noise', 'gp.hyper.sd', 'gp.mean.affine',
             'gp.mean.descriptor', 'acquisition.ucb.alpha', 'acquisition.caution',
             'acquisition.progress', 'acquisition.reach', 'goal.eps',
             'fall.risk.threshold', 'fall.risk.cost', 'fall.kernel.sigma', 'priors.max_misfit',
             'priors.max_misfit_reproduced', 'priors.weights.sd', 'planner.horizon',
             'planner.lookahead', 'planner.reach')
# Parameter name -> SELAConfig key, where they differ: the node's names must nest in the YAML
# of ``ros2 param dump`` (no name a prefix of another); the core's keys are what the
# experiments record.
SELA_NAMES = {'priors.max_misfit': 'priors.max.misfit',
              'priors.max_misfit_reproduced': 'priors.max.misfit.reproduced'}
#: Stepper settings, and the type each is read as (changeable at run time: the timings).
STEPPER_KEYS = {'max_steps': int, 'detector_timeout': float, 'outcome_timeout': float,
                'outcome_attempts': int, 'outcome.max_refused': int,
                'adapt_on_start': bool, 'reset_on_fall': bool,
                'adaptation.on_detection': str, 'outcome.max_displacement': float,
                'max_observations': int}
# Parameter name -> StepperConfig field, where they differ.
_FIELDS = {'adaptation.on_detection': 'on_detection',
           'outcome.max_displacement': 'max_displacement',
           'outcome.max_refused': 'max_refused_steps'}


def sela_config(values):
    """The SELA parameters among the node's ``values``, keyed as SELAConfig reads them."""
    return {SELA_NAMES.get(k, k): values[k] for k in SELA_KEYS}


def stepper_fields():
    """``{parameter name: StepperConfig field}`` of the stepper's parameters."""
    return {k: _FIELDS.get(k, k) for k in STEPPER_KEYS}


def stepper_config(values, archive=None):
    """The stepper's configuration from the node's ``values`` (``auto`` ones: ``archive``'s)."""
    fields = stepper_fields()
    return StepperConfig(**{fields[k]: t(_resolved(k, values[k], archive))
                            for k, t in STEPPER_KEYS.items()})


def stepper_change(name, value, archive=None):
    """``{field: value}`` for :meth:`MissionStepper.configure` ({} if not a stepper's)."""
    if name not in STEPPER_KEYS:
        return {}
    return {_FIELDS.get(name, name): STEPPER_KEYS[name](_resolved(name, value, archive))}


def _resolved(name, value, archive):
    if name == 'outcome.max_displacement' and value == AUTO:
        return (StepperConfig.max_displacement if archive is None
                else archive_displacement_limit(archive.generic_reward))
    return value
