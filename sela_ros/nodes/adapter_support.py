"""What the ``sela_adapter`` decides about its archive and goals, apart from its
translate-and-dispatch layer (:mod:`sela_ros.nodes.adapter_node`): which damage priors and
stepper an archive gets, when the archive may change, what a new stepper carries over,
goals its map rules out, the planner's answer as an event. Functions of values: the node
keeps its own state.
"""
import os

from sela_ros.core.learning import DamagePriorError, resolve_priors
from sela_ros.core.mission import MissionStepper, make_sela
from sela_ros.core.mission import stepper_io as io
from sela_ros.core.storage import ArchiveError, load_archive, resolve_archive_path
from sela_ros.nodes import adapter_params as params


def _listed(names, most=16):
    """``names`` joined, or past ``most`` of them, counted by their kinds of damage (the
    first word of each part: '15 remove+remove, 18 shorten, ...')."""
    if len(names) <= most:
        return ', '.join(names)
    kinds = {}
    for name in names:
        kind = '+'.join(part.split(':')[0] for part in name.split(','))
        kinds[kind] = kinds.get(kind, 0) + 1
    return ', '.join(f'{n} {kind}' for kind, n in kinds.items())


def load_priors(setting, archive, path, logger):
    """The damage priors ``setting`` (the ``priors.tables`` parameter) names for ``archive``; None
    (logged) if there are none or they cannot be used: SELA then adapts from the intact map
    alone."""
    try:
        priors = resolve_priors(setting, path, archive.params)
    except DamagePriorError as exc:
        logger.error(f'{exc}; adapting from the intact map alone')
        return None
    if priors is not None:
        first = priors.first_tier()
        second = priors.names[len(first):]
        logger.info(f'damage priors: {len(first)} foreseen damages ({", ".join(first.names)})'
                    + (f'; {len(second)} more, each used once it reproduces the robot\'s '
                       f'standing starts ({_listed(second)})' if second else ''))
        partly = [i for i in range(len(priors)) if priors.inferred(i) is not None]
        if partly:
            counts = sorted({int((~priors.inferred(i)).sum()) for i in partly})
            span = '-'.join(map(str, (counts[0], counts[-1])[:len(counts)]))
            logger.info(f'damage priors: {len(partly)} tables partly inferred (each simulated '
                        f'{span} of {priors.num_candidates} gaits): while one is the prior, '
                        'the choice is among the gaits it simulated and those the robot has '
                        'tried')
    return priors


def new_stepper(values, archive, priors, next_id=1, self_model=None):
    """A stepper over ``archive`` with the node's parameter ``values``; command ids from
    ``next_id`` (they stay unique across archives); ``self_model``: its self-model
    (:func:`self_model`), or None."""
    return MissionStepper(make_sela(archive, params.sela_config(values), priors=priors),
                          params.stepper_config(values, archive), next_id=next_id,
                          self_model=self_model)


def self_model(values, archive):
    """``(SelfModel, robot, why not)`` for ``archive`` with the node's ``values``: the
    self-model (None: none) and what finds the robot's simulator in a worker
    (``sim_bridge.robots.robot_spec``); ``why not``: the reason there is none though
    ``self_model.enabled`` asks for one ('' if it is off or there is one)."""
    if not values['self_model.enabled']:
        return None, None, ''
    try:
        from sela_ros.core.learning.self_model import SelfModelConfig, from_archive
        from sim_bridge.robots import get_robot, robot_of, robot_spec

        robot = get_robot(robot_of(archive.metadata))
        gaits = int(values['self_model.gaits'])
        config = SelfModelConfig(gaits=gaits, covering=gaits // 2,
                                 refine=int(values['self_model.refine']))
        model = from_archive(archive, robot.legs, config, robot.vocabulary.kinds)
        return model, robot_spec(robot), ''
    except (ImportError, ValueError) as exc:
        return None, None, f'no self-model: {exc}'


def carried_over(old):
    """The events that carry a mission in progress on ``old`` (a stepper, or None) over to a
    new stepper: it goes on with the goals, from where the robot is."""
    if old is None or old.goal is None or old.state is io.State.DONE:
        return []
    events = [] if old.odom is None else [io.PoseObserved(tuple(old.odom), old.odom_stamp)]
    return events + [io.GoalsReceived((tuple(old.goal), *map(tuple, old.goals_left)))]


def archive_change(value, in_use, stepper, node_name, mismatch=None):
    """Can the ``archive`` parameter become ``value`` now? ``(problem, path, archive)``:
    ``problem`` says why not; else ``archive`` is the file loaded from ``path`` to use, or
    None when it is the file in use (``in_use``: kept, with what was learned on it).

    A file that cannot be loaded, or built for other physics than the simulator's
    (``mismatch(archive, path)``: the reason, or None), is refused with its problem,
    whatever the adapter is doing. Another file would make what was learned meaningless
    (its indices are the old archive's gaits): refused mid-step, and while anything is
    learned, until ``~/clear``.
    """
    path = resolve_archive_path(value)
    if in_use is not None and same_file(path, in_use):
        return None, path, None
    try:  # first: a file that cannot be used is refused for what is wrong with it
        archive = load_archive(path)
    except ArchiveError as exc:
        return str(exc), path, None
    problem = mismatch(archive, path) if mismatch is not None else None
    if problem:
        return (f'archive {path} refused: {problem}, set when it started: start both '
                'with the same archive (ros2 launch sela_ros ... archive:=NAME)'), path, None
    if stepper is not None and stepper.state not in (io.State.IDLE, io.State.DONE,
                                                     io.State.READY):
        return (f'archive {path} refused: it cannot change mid-step; set it again between '
                'steps'), path, None
    learned = 0 if stepper is None else len(stepper.sela.observations[0])
    if learned:
        return (f'archive {path} refused: {learned} observation(s) were learned on {in_use} '
                f'and would be lost; call {node_name}/clear first, then set the archive '
                'again'), path, None
    return None, path, archive


def same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError, TypeError):
        return False


def goal_refusal(grid, goal, stepper):
    """Why a goal off the planner's map (``grid``) or inside an obstacle is refused, or None
    (without a map: the planner decides). A mission in progress goes on."""
    problem = None if grid is None else grid.goal_problem(goal)
    if problem is None:
        return None
    running = stepper is not None and stepper.running()
    return (f'goal ({goal[0]:.2f}, {goal[1]:.2f}) refused: {problem}'
            + (f'; the mission to ({stepper.goal[0]:.2f}, {stepper.goal[1]:.2f}) goes on'
               if running else ''))


def plan_event(answer, command, grid=None):
    """``planner/make_plan``'s answer to ``command`` as an event: the whole path to the goal
    (the stepper takes the waypoints off it); an empty one (or no answer: None) means no
    path, and why is said from the planner's map (``grid``) where it shows (a goal that came
    before the map did is not refused on arrival: the planner's empty answer is)."""
    poses = answer.plan.poses if answer is not None else []
    path = tuple((p.pose.position.x, p.pose.position.y) for p in poses) or None
    problem = None if grid is None else grid.goal_problem(command.goal)
    reason = ('the planner did not answer' if answer is None
              else f'goal ({command.goal[0]:.2f}, {command.goal[1]:.2f}) is {problem}'
              if problem else 'the planner found no path (it says why on diagnostics)')
    return io.PlanReceived(command.step, tuple(command.start), reason=reason, path=path)
