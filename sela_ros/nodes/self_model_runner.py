"""The self-model's simulations beside the mission: the robot's simulator in worker processes.

The ``sela_adapter`` node's stepper asks for a damage hypothesis to be simulated
(:class:`~sela_ros.core.mission.stepper_io.SimulateDamage`: the legs the feet say are lost,
:mod:`sela_ros.core.learning.self_model`); this runs it on ``self_model.workers`` processes
(started at the first request, never forked from the node) while the robot walks, and hands
the answer back as a :class:`~sela_ros.core.mission.stepper_io.DamageSimulated` that the
node's timer feeds to the stepper. No callback waits on it.
"""
from sela_ros.core.mission import stepper_io as io


def _answer(command, params, settings, robot):
    """A worker's job: :func:`~sela_ros.core.mission.answer_request` on the robot's simulator
    (``params``: the archive's gaits)."""
    from sela_ros.core.mission import answer_request
    from sim_bridge.evaluation import simulate_gaits

    return answer_request(command, lambda damage, gaits: simulate_gaits(
        params[gaits], damage, settings, robot))


class SelfModelSimulations:
    """Args:
        params: ``(M, P)`` the archive's gait parameters.
        settings: the archive's simulator settings (``dt``, ``gait_duration``, ...).
        robot: what finds the robot's description in a worker (``sim_bridge.robots.
            robot_spec``).
        workers: processes at most (one answers each request).
    """

    def __init__(self, params, settings, robot, workers=1):
        self.params, self.settings, self.robot = params, dict(settings), robot
        self.workers = max(1, int(workers))
        self._pool = None
        self._running = []  # (SimulateDamage, future)

    def submit(self, command: io.SimulateDamage) -> None:
        """Start answering ``command`` in a worker."""
        from sim_bridge.evaluation import worker_pool

        if self._pool is None:
            self._pool = worker_pool(self.workers)
        self._running.append((command, self._pool.submit(
            _answer, command, self.params, self.settings, self.robot)))

    @property
    def busy(self) -> int:
        """Simulations not answered yet."""
        return len(self._running)

    def poll(self) -> list:
        """The answers of the simulations that have finished (a failure's with its reason)."""
        out = []
        for item in [r for r in self._running if r[1].done()]:
            self._running.remove(item)
            command, future = item
            try:
                out.append(future.result())
            except Exception as exc:  # a worker that died, a robot it cannot build
                out.append(io.DamageSimulated(command.damage, command.gaits,
                                              error=f'{type(exc).__name__}: {exc}'))
        return out

    def cancel(self) -> None:
        """Drop every simulation under way (the archive changed: its gaits are others)."""
        for _, future in self._running:
            future.cancel()
        self._running = []

    def close(self) -> None:
        self.cancel()
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
