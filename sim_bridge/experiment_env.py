"""The damaged robot as a ``sela_ros.experiments.baselines.Environment``, and the oracle's table.

ROS-free. :class:`RobotEnvironment` (also named :class:`HexapodEnvironment`) lets the
in-process experiment (``sela-experiment hexapod``) drive a simulated robot (the hexapod by
default, any description of :mod:`sim_bridge.robots`) through the same runners as the
toy world: ``execute(index)`` runs gait ``index`` of the archive from wherever the robot
stands (never a reset inside a replicate), and position observations carry the paper's
Gaussian noise (:class:`sim_bridge.environment.ObservedHexapod`).

A fallen robot (see :meth:`Simulator.is_fallen`) gets up where it lies after the gait that
tipped it (:meth:`Simulator.right`), as the ``sim_bridge`` node's robot does by default. The
gait still counts as a step; :attr:`HexapodEnvironment.falls` counts them.

:func:`oracle_table` evaluates every archive gait on the damaged robot from a standing
start (``evaluate_gait``), in parallel, cached on disk per (archive checksum, damage,
simulator settings, whose stamp names the robot's model): the damaged robot's true generic
rewards that the oracle plans with.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import time
from pathlib import Path

import numpy as np

from sela_ros.core.learning import params_checksum
from sela_ros.core.storage import atomic_write
from sim_bridge.environment import ObservedHexapod
from sim_bridge.evaluation import evaluate_gait, worker_pool
from sim_bridge.robots import get_robot, robot_spec
from sim_bridge.settings import SIM_DEFAULTS, simulator_settings
from sim_bridge.simulator import Simulator

ORACLE_FORMAT_VERSION = 1


class RobotEnvironment:
    """The robot with ``damage``, executing gaits of an archive by index.

    Args:
        params: ``(M, n_params)`` controller parameters of the archive's gaits.
        damage: damage spec (``sim_bridge.damage`` grammar, the robot's names), applied from
            the start.
        noise_std: standard deviation (m) of the noise on each observed coordinate.
        seed: seed of the observation noise.
        dt, gait_duration, solver_iterations: simulator settings (must match the archive's).
        robot: a name or description (:func:`sim_bridge.robots.get_robot`; None: hexapod).

    Attributes:
        falls: gaits after which the robot had fallen (and was righted) since ``reset``.
        standing: whether the next gait starts from a standing start (after ``reset`` and
            after a righting), as the damage priors' tables ran every gait.
        sim_seconds: wall-clock seconds spent inside the simulator (``execute``).
    """

    def __init__(self, params, damage='intact', noise_std=0.0, seed=0,
                 dt=1.0 / 240.0, gait_duration=3.0, solver_iterations=50, robot=None):
        description = get_robot(robot)
        params = np.asarray(params, dtype=float)
        if params.ndim != 2 or params.shape[1] != description.n_params:
            raise ValueError(f'params must have shape (M, {description.n_params}) for the '
                             f'{description.name}, got {params.shape}')
        self.params = params
        self.robot = Simulator(dt=dt, gait_duration=gait_duration,
                               damage=description.parse_damage(damage),
                               solver_iterations=solver_iterations, robot=description)
        self.observed = ObservedHexapod(self.robot, noise_std=noise_std, seed=seed)
        self.falls = 0
        self.sim_seconds = 0.0
        self.last_execution = None  # the last gait's Execution (its feet: duty_factors)
        self._moved = False  # a gait ran since the robot was built or reset

    def close(self) -> None:
        self.robot.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def reset(self) -> None:
        """Standing at the origin, yaw 0, with the damage (start of a replicate).

        A new environment is there already: it keeps its first observation, as the
        ``sim_bridge`` node does at start-up, so that the same ``seed`` draws the same
        observation noise in process and over DDS."""
        if self._moved:
            self.observed.reset()
        self._moved = False
        self.falls = 0

    @property
    def standing(self) -> bool:
        """Whether the next gait starts from a standing start (``Simulator.standing``)."""
        return self.robot.standing

    def observed_pose(self) -> np.ndarray:
        return self.observed.observed_pose()

    def true_pose(self) -> np.ndarray:
        return self.observed.true_pose()

    def execute(self, index: int) -> np.ndarray:
        """Run gait ``index`` from the current state; return the observed pose after it."""
        index = int(index)
        if not 0 <= index < len(self.params):
            raise IndexError(f'gait index {index} outside the archive (0..{len(self.params) - 1})')
        start = time.perf_counter()
        # A fallen robot gets up where it lies (ObservedHexapod): the observation after the
        # gait stays valid.
        self._moved = True
        execution = self.last_execution = self.observed.execute(self.params[index])
        if execution.fallen:
            self.falls += 1
        self.sim_seconds += time.perf_counter() - start
        return self.observed.observed_pose()


#: The name the hexapod's experiments have always used.
HexapodEnvironment = RobotEnvironment


# --------------------------------------------------------------------------- oracle table


def archive_checksum(params) -> str:
    """SHA-256 of the archive's gait parameters (float64, C order)."""
    return params_checksum(params)


def default_cache_dir() -> Path:
    """``$SELA_CACHE_DIR`` or ``~/.cache/sela_ros/oracle``."""
    env = os.environ.get('SELA_CACHE_DIR')
    return Path(env) if env else Path.home() / '.cache' / 'sela_ros' / 'oracle'


def oracle_cache_path(params, damage, cache_dir=None, dt=1.0 / 240.0,
                      gait_duration=3.0, solver_iterations=50, robot=None) -> Path:
    description = get_robot(robot)
    settings = simulator_settings(dt, gait_duration, solver_iterations, robot=description)
    parts = [archive_checksum(params), description.parse_damage(damage).canonical(),
             repr(settings['dt']), repr(settings['gait_duration']),
             settings['controller_version'], settings['model_version'],
             str(ORACLE_FORMAT_VERSION)]
    if settings['solver_iterations'] != SIM_DEFAULTS['solver_iterations']:
        parts.append(f"iterations={settings['solver_iterations']}")  # old caches stay valid
    key = '|'.join(parts)
    digest = hashlib.sha256(key.encode()).hexdigest()[:24]
    return Path(cache_dir or default_cache_dir()) / f'oracle_{digest}.npz'


def _evaluate_chunk(job):
    chunk, damage, dt, gait_duration, solver_iterations, robot = job
    out = np.empty((len(chunk), 4))
    for i, params in enumerate(chunk):
        outcome = evaluate_gait(params, damage, dt, gait_duration, solver_iterations, robot)
        out[i, :3] = outcome.generic_reward
        out[i, 3] = float(outcome.fallen)
    return out


def compute_oracle_table(params, damage, workers=1, dt=1.0 / 240.0, gait_duration=3.0,
                         solver_iterations=50,
                         chunk_size=25, robot=None, progress=None):
    """``(generic_reward (M, 3), fallen (M,))`` of every gait on the damaged robot;
    ``progress`` (if given) is called with the number of gaits of each chunk done."""
    params = np.asarray(params, dtype=float)
    description = get_robot(robot)
    spec = description.parse_damage(damage).canonical()
    chunks = [params[i:i + chunk_size] for i in range(0, len(params), chunk_size)]
    # The robot travels to worker processes as a string that finds it there.
    jobs = [(c, spec, dt, gait_duration, solver_iterations, robot_spec(description))
            for c in chunks]
    rows = []
    with contextlib.ExitStack() as stack:
        if workers <= 1 or len(chunks) <= 1:
            done = map(_evaluate_chunk, jobs)
        else:
            done = stack.enter_context(worker_pool(workers)).map(_evaluate_chunk, jobs)
        for row in done:
            rows.append(row)
            if progress is not None:
                progress(len(row))
    table = np.concatenate(rows) if rows else np.zeros((0, 4))
    return table[:, :3], table[:, 3].astype(bool)


def cached_oracle_table(params, damage, cache_dir=None, dt=1.0 / 240.0, gait_duration=3.0,
                        solver_iterations=50, robot=None):
    """The oracle table of :func:`oracle_table` if it is cached, whole and sound; else None
    (nothing is computed)."""
    path = oracle_cache_path(params, damage, cache_dir, dt, gait_duration, solver_iterations,
                             robot)
    n = len(params)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as npz:
            gr, fallen = npz['generic_reward'], npz['fallen']
    except Exception:  # corrupt or truncated: as if absent
        return None
    if gr.shape == (n, 3) and fallen.shape == (n,) and np.all(np.isfinite(gr)):
        return gr.astype(float), fallen.astype(bool)
    return None


def oracle_table(params, damage, workers=1, cache_dir=None, dt=1.0 / 240.0,
                 gait_duration=3.0, solver_iterations=50, robot=None, progress=None):
    """:func:`compute_oracle_table`, cached on disk (atomic write; a bad file is redone);
    ``progress`` is called only when the table is computed.

    Returns:
        ``(generic_reward (M, 3), fallen (M,))``.
    """
    cached = cached_oracle_table(params, damage, cache_dir, dt, gait_duration,
                                 solver_iterations, robot)
    if cached is not None:
        return cached
    description = get_robot(robot)
    path = oracle_cache_path(params, damage, cache_dir, dt, gait_duration, solver_iterations,
                             description)
    gr, fallen = compute_oracle_table(params, damage, workers, dt, gait_duration,
                                      solver_iterations, robot=description, progress=progress)
    atomic_write(path, lambda handle: np.savez(
        handle, generic_reward=gr, fallen=fallen,
        damage=np.array(description.parse_damage(damage).canonical())))
    return gr, fallen


# --------------------------------------------------------------------------- chained runs


def chained_runs(params, damage, gaits, predecessors, workers=1, dt=1.0 / 240.0,
                 gait_duration=3.0, solver_iterations=50, cache_dir=None, robot=None):
    """Each of ``gaits`` run right after each of its ``predecessors`` (``(len(gaits), R)``
    archive indices), every pair from a standing start: ``(runs, falls)`` per gait, the
    pairs whose predecessor fell left out. What a table from standing starts cannot say:
    whether a gait tips the robot over when it starts where another gait left the legs
    (``scripts/build_priors.py``; the fall model uses it, ``FallRisk.risk``). ``robot``: as
    :func:`get_robot` takes it (None: the hexapod)."""
    gaits = np.asarray(gaits, dtype=int).reshape(-1)
    if not gaits.size:  # a damage whose gaits the fall model does not fear (a middle leg)
        return np.zeros(0, int), np.zeros(0, int)
    predecessors = np.asarray(predecessors, dtype=int).reshape(len(gaits), -1)
    description = get_robot(robot)
    spec = description.parse_damage(damage).canonical()
    # Cached beside the oracle tables, keyed by everything the runs depend on.
    key = hashlib.sha256(b'|'.join([oracle_cache_path(params, damage, cache_dir, dt,
                                                      gait_duration, solver_iterations,
                                                      description).stem.encode(),
                                    gaits.tobytes(), predecessors.tobytes()])).hexdigest()
    path = Path(cache_dir or default_cache_dir()) / f'chained_{key[:24]}.npz'
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as npz:
                runs, falls = npz['runs'], npz['falls']
            if runs.shape == falls.shape == gaits.shape:
                return runs.astype(int), falls.astype(int)
        except Exception:  # corrupt or truncated: run them again below
            pass
    chunks = np.array_split(np.arange(len(gaits)), max(1, min(len(gaits), 4 * workers)))
    jobs = [(np.asarray(params, float)[gaits[c]], np.asarray(params, float)[predecessors[c]],
             spec, dt, gait_duration, solver_iterations, robot_spec(description))
            for c in chunks if len(c)]
    if workers <= 1 or len(jobs) <= 1:
        rows = [_chained_chunk(j) for j in jobs]
    else:
        with worker_pool(workers) as pool:
            rows = list(pool.map(_chained_chunk, jobs))
    out = np.concatenate(rows) if rows else np.zeros((0, 2), int)
    atomic_write(path, lambda handle: np.savez(handle, runs=out[:, 0], falls=out[:, 1]))
    return out[:, 0], out[:, 1]


def _chained_chunk(job):
    gaits, predecessors, damage, dt, gait_duration, solver_iterations, robot = job
    out = np.zeros((len(gaits), 2), int)
    with Simulator(dt=dt, gait_duration=gait_duration, damage=damage,
                   solver_iterations=solver_iterations, robot=get_robot(robot)) as robot:
        for i, (gait, before) in enumerate(zip(gaits, predecessors)):
            for first in before:
                robot.reset()
                if robot.execute(first).fallen:
                    continue
                out[i] += (1, int(robot.execute(gait).fallen))
    return out
