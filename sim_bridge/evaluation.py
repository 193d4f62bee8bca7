"""One gait from a fresh standing start, on cached simulators: the robot's evaluation for
map building (picklable, so worker processes of the map builder call it), and the pool of
fresh worker processes that the map builder and the experiments run such work in."""
from __future__ import annotations

import multiprocessing
from collections import OrderedDict
from concurrent.futures import ProcessPoolExecutor

from sim_bridge.robots import get_robot
from sim_bridge.settings import SIM_DEFAULTS, simulator_settings
from sim_bridge.simulator import GaitOutcome, Simulator

_CACHE: OrderedDict = OrderedDict()
_CACHE_SIZE = 4


def _cached_simulator(damage, dt, gait_duration, solver_iterations, robot) -> Simulator:
    description = get_robot(robot)
    spec = description.parse_damage(damage)
    settings = simulator_settings(dt, gait_duration, solver_iterations)
    key = (description.name, spec, settings['dt'], settings['gait_duration'],
           settings['solver_iterations'])
    sim = _CACHE.get(key)
    if sim is None:
        sim = Simulator(dt=settings['dt'], gait_duration=settings['gait_duration'],
                        damage=spec, solver_iterations=settings['solver_iterations'],
                        robot=description)
        _CACHE[key] = sim
        while len(_CACHE) > _CACHE_SIZE:
            _, old = _CACHE.popitem(last=False)
            old.close()
    else:
        _CACHE.move_to_end(key)
    return sim


def evaluate_gait(params, damage='intact', dt: float = SIM_DEFAULTS['dt'],
                  gait_duration: float = SIM_DEFAULTS['gait_duration'],
                  solver_iterations: int = SIM_DEFAULTS['solver_iterations'],
                  robot=None) -> GaitOutcome:
    """One gait from a fresh standing start at the origin (deterministic, picklable).

    Uses a per-process cache of simulators (one per robot/damage/dt/duration, reset with
    ``restoreState``), so it is cheap to call many times in a worker process.
    ``sim_time`` of the outcome is the gait duration. ``robot``: a name or description
    (:func:`sim_bridge.robots.get_robot`; None: the hexapod).
    """
    sim = _cached_simulator(damage, dt, gait_duration, solver_iterations, robot)
    sim.reset(clock=True)
    return sim.execute(params)


def simulate_gaits(params, damage, settings=None, robot=None):
    """``(generic rewards (n, 3), fallen (n,), duty factors (n, legs))`` of each gait of
    ``params`` ``(n, P)`` from a fresh standing start on ``damage``: a damage hypothesis's
    outcomes for the self-model
    (:mod:`sela_ros.core.learning.self_model`). ``settings``: the map's simulator settings
    (``dt``, ``gait_duration``, ``solver_iterations``; None: the defaults)."""
    import numpy as np

    settings = {**SIM_DEFAULTS, **(settings or {})}
    outcomes = [evaluate_gait(p, damage, settings['dt'], settings['gait_duration'],
                              settings['solver_iterations'], robot) for p in params]
    legs = len(get_robot(robot).legs)
    return (np.array([o.generic_reward for o in outcomes], dtype=float).reshape(-1, 3),
            np.array([o.fallen for o in outcomes], dtype=bool),
            np.array([o.duty_factors for o in outcomes], dtype=float).reshape(-1, legs))


def worker_pool(workers: int) -> ProcessPoolExecutor:
    """A pool of ``workers`` processes that start from a fresh ``forkserver`` (``spawn``
    where unavailable), never from a fork of the caller: a forked worker would inherit the
    caller's PyBullet connections and threads (a test session's, a notebook's)."""
    methods = multiprocessing.get_all_start_methods()
    context = multiprocessing.get_context('forkserver' if 'forkserver' in methods
                                          else 'spawn')
    return ProcessPoolExecutor(max_workers=workers, mp_context=context)
