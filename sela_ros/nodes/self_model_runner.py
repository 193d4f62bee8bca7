"""The self-model's simulations beside the mission: the robot's simulator in worker processes.

The ``sela_adapter`` node's stepper asks for a damage hypothesis to be simulated
(:class:`~sela_ros.core.mission.stepper_io.SimulateDamage`: the legs the feet say are lost,
:mod:`sela_ros.core.learning.self_model`); this runs it on ``self_model.workers`` processes
(started at the first request, never forked from the node) while the robot walks: first the
damage it settles on (a leg the others tilt off the ground told apart, on the few gaits the
robot ran), then that damage's gaits, shared among the workers. It hands
the answer back as a :class:`~sela_ros.core.mission.stepper_io.DamageSimulated` that the
node's timer feeds to the stepper. No callback waits on it.
"""
from concurrent.futures import Future

import numpy as np

from sela_ros.core.mission import stepper_io as io


def _simulator(params, settings, robot):
    from sim_bridge.evaluation import simulate_gaits

    return lambda damage, gaits: simulate_gaits(params[gaits], damage, settings, robot)


def _settle(command, params, settings, robot):
    """A worker's first job: the damage the request settles on
    (:func:`~sela_ros.core.mission.settle_request`)."""
    from sela_ros.core.mission import settle_request

    return settle_request(command, _simulator(params, settings, robot))


def _simulate(damage, params, settings, robot):
    """A worker's share of the gaits (``params``, theirs) simulated on ``damage``."""
    from sim_bridge.evaluation import simulate_gaits

    return simulate_gaits(params, damage, settings, robot)


class _Request:
    """One request's way through the workers: the damage settled on, then its gaits in
    shares."""

    def __init__(self, command, future):
        self.command, self.future, self.damage, self.shares = command, future, None, None

    def futures(self):
        return [self.future] if self.shares is None else self.shares


class SelfModelSimulations:
    """Args:
        params: ``(M, P)`` the archive's gait parameters.
        settings: the archive's simulator settings (``dt``, ``gait_duration``, ...).
        robot: what finds the robot's description in a worker (``sim_bridge.robots.
            robot_spec``).
        workers: processes, among which each request's gaits are shared.
    """

    def __init__(self, params, settings, robot, workers=1):
        self.params, self.settings, self.robot = params, dict(settings), robot
        self.workers = max(1, int(workers))
        self._pool = None
        self._running = []  # _Request

    def submit(self, command: io.SimulateDamage) -> None:
        """Start answering ``command``: the damage it settles on in one worker (the gaits the
        robot ran, a few; none to settle without the feet), then its gaits shared among the
        workers."""
        from sim_bridge.evaluation import worker_pool

        if self._pool is None:
            self._pool = worker_pool(self.workers)
        if command.feet is None:  # more gaits of a damage already settled on (a refinement)
            settled = Future()
            settled.set_result(command.damage)
        else:
            settled = self._pool.submit(_settle, command, self.params, self.settings,
                                        self.robot)
        self._running.append(_Request(command, settled))

    @property
    def busy(self) -> int:
        """Simulations not answered yet."""
        return len(self._running)

    def poll(self) -> list:
        """The answers of the simulations that have finished (a failure's with its reason)."""
        from sela_ros.core.mission import simulated_answer

        out = []
        for request in [r for r in self._running if all(f.done() for f in r.futures())]:
            command = request.command
            try:
                if request.shares is None:  # settled: now its gaits, in shares
                    request.damage = request.future.result()
                    gaits = np.asarray(command.gaits, dtype=int)
                    request.shares = [self._pool.submit(
                        _simulate, request.damage, self.params[share], self.settings,
                        self.robot) for share in np.array_split(gaits, self.workers)
                        if share.size]
                    continue
                parts = [f.result() for f in request.shares]
            except Exception as exc:  # a worker that died, a robot it cannot build
                self._running.remove(request)
                out.append(io.DamageSimulated(command.damage, command.gaits,
                                              error=f'{type(exc).__name__}: {exc}'))
                continue
            self._running.remove(request)
            out.append(simulated_answer(command, request.damage,
                                        np.concatenate([p[0] for p in parts]),
                                        np.concatenate([p[1] for p in parts])))
        return out

    def cancel(self) -> None:
        """Drop every simulation under way (the archive changed: its gaits are others)."""
        for request in self._running:
            for future in request.futures():
                future.cancel()
        self._running = []

    def close(self) -> None:
        self.cancel()
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
