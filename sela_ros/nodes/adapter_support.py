"""What the ``sela_adapter`` keeps and checks: which archive is in use and when it may
change, resuming what was learned at start-up, goals its map rules out. Functions over the
node, kept apart from its translate-and-dispatch layer (:mod:`sela_ros.nodes.adapter_node`).
"""
import os

from sela_ros.core import persistence
from sela_ros.core import stepper_io as io
from sela_ros.core.archive import ArchiveError, load_archive
from sela_ros.core.archive_paths import resolve_archive_path
from sela_ros.core.damage_priors import DamagePriorError, resolve_priors
from sela_ros.core.learning import make_sela
from sela_ros.core.stepper import MissionStepper
from sela_ros.nodes import adapter_params as params


def _priors(node, archive, path):
    """The damage priors the ``priors.tables`` parameter names for ``archive``; None (logged) if
    there are none or they cannot be used: SELA then adapts from the intact map alone."""
    try:
        priors = resolve_priors(node.values['priors.tables'], path, archive.params)
    except DamagePriorError as exc:
        node.get_logger().error(f'{exc}; adapting from the intact map alone')
        return None
    if priors is not None:
        node.get_logger().info(f'damage priors: {len(priors)} foreseen damages '
                               f'({", ".join(priors.names)})')
    return priors


def _new_stepper(node, archive):
    return MissionStepper(make_sela(archive, params.sela_config(node.values),
                                    priors=node.priors),
                          params.stepper_config(node.values))


def use_archive(node, path, archive=None):
    """Load the archive at ``path`` ('': the shipped one; ``8d``, ``2d``: the shipped ones by
    name; ``archive``: already loaded from there) and a stepper over it; a mission in
    progress goes on with the new archive, from where the robot is."""
    path = resolve_archive_path(path)
    archive, old = archive if archive is not None else load_archive(path), node.stepper
    node.archive, node.archive_path = archive, path
    node.priors = _priors(node, archive, path)
    node.stepper = _new_stepper(node, archive)
    node.sim_check.use(archive, path)
    node.get_logger().info(f'archive {path}: {len(archive)} behaviours, '
                           f'{archive.descriptors.shape[1]}-D descriptors, kernel length '
                           f'{node.stepper.sela.config.gp_kernel_sigma:g}')
    if old is not None:
        node.stepper.next_id = old.next_id  # command ids stay unique across archives
    if old is not None and old.goal is not None and old.state is not io.State.DONE:
        if old.odom is not None:  # the new stepper goes on with the goal, from here
            node._feed(io.PoseObserved(tuple(old.odom), old.odom_stamp))
        node._feed(io.GoalsReceived((tuple(old.goal), *map(tuple, old.goals_left))))


def archive_change(node, value):
    """Why ``archive`` cannot become ``value`` now, or None (then it is in use).

    The same file again keeps everything (nothing to load). A file that cannot be loaded is
    refused with its problem, whatever the adapter is doing. Another file would make what
    was learned meaningless (its indices are the old archive's gaits): refused mid-step,
    and while anything is learned, until ``~/clear``.
    """
    path = resolve_archive_path(value)
    if node.archive is not None and same_file(path, node.archive_path):
        node.get_logger().info(f'archive {path} is the one in use: kept, with what was '
                               'learned on it')
        return None
    try:  # first: a file that cannot be used is refused for what is wrong with it
        archive = load_archive(path)
    except ArchiveError as exc:
        return str(exc)
    if node.stepper is not None and node.stepper.state not in (
            io.State.IDLE, io.State.DONE, io.State.READY):
        return f'archive {path} refused: it cannot change mid-step; set it again between steps'
    learned = 0 if node.stepper is None else len(node.stepper.sela.observations[0])
    if learned:
        return (f'archive {path} refused: {learned} observation(s) were learned on '
                f'{node.archive_path} and would be lost; call '
                f'{node.get_name()}/clear first, then set the archive again')
    use_archive(node, path, archive)
    return None


def resume(node):
    """Take back what the state file holds; an unusable file is set aside with the reason."""
    path = node.store.path
    restored = []

    def restore(state):
        # Into a fresh stepper, swapped in only once all of it came back.
        stepper = _new_stepper(node, node.archive)
        restored.extend(stepper.restore(state, node.now()))
        node.stepper = stepper

    state, problem = persistence.resume_state(path, len(node.archive), restore)
    if problem:
        node._report(io.Level.ERROR, problem)
        return
    node._dispatch(restored)
    if state is not None:
        mode = 'adapting' if node.stepper.logic.adapting else 'trusting the map'
        node.get_logger().warn(f'resumed from {path}: '
                               f'{len(node.stepper.sela.observations[0])} observation(s), '
                               f'{mode}')


def same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError, TypeError):
        return False


def goal_refused(node, goal):
    """A goal off the planner's map or inside an obstacle cannot be planned: refused
    here, and a mission in progress goes on (without a map: the planner decides)."""
    problem = None if node.map is None else node.map.goal_problem(goal)
    if problem is None:
        return False
    running = node.stepper is not None and node.stepper.goal is not None and \
        node.stepper.state not in (io.State.IDLE, io.State.DONE)
    node._report(io.Level.ERROR, f'goal ({goal[0]:.2f}, {goal[1]:.2f}) refused: {problem}'
                 + (f'; the mission to ({node.stepper.goal[0]:.2f}, '
                    f'{node.stepper.goal[1]:.2f}) goes on' if running else ''))
    return True


def plan_event(answer, command):
    """``planner/make_plan``'s answer to ``command`` as an event: the whole path to the goal
    (the stepper takes the waypoints off it); an empty one (or no answer: None) means no
    path."""
    poses = answer.plan.poses if answer is not None else []
    path = tuple((p.pose.position.x, p.pose.position.y) for p in poses) or None
    reason = ('the planner did not answer' if answer is None
              else 'the planner found no path (it says why on diagnostics)')
    return io.PlanReceived(command.step, tuple(command.start), reason=reason, path=path)
