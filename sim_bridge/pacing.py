"""One gait against the wall clock: its state messages spaced, its pace held.

The simulator runs a gait as fast as the machine allows (about 20 times real time for the
hexapod here). Watched in RViz, Foxglove or PyBullet's window, or driven by a client that
expects a robot's pace, it can instead be held to a chosen multiple of real time
(``real_time_factor``): the gait's step callback waits until the wall clock has caught up
with the simulated time it reached. Without ROS, so that it is tested alone.
"""
from __future__ import annotations

import time

PACE_PERIOD = 0.02  # s of sim time between looks at the wall clock while a gait is paced
MIN_REAL_TIME_FACTOR = 0.1  # a real_time_factor is 0 (no pacing) or at least this


class GaitPace:
    """The step callback of one gait (``Simulator.execute``'s ``callback``).

    Args:
        on_state: ``on_state(sim_time, pose, joint_positions, joint_velocities)``, called
            every ``publish_period`` of sim time, at most ``max_rate`` times per wall second
            (None: no cap), and at ``end`` whatever the cap.
        start: sim time at the gait's start.
        publish_period: sim time between two calls of ``on_state``.
        dt: the physics step (the tolerance on sim times).
        max_rate: Hz of wall time, or None.
        real_time_factor: the gait lasts its sim time divided by this in wall time at least;
            0 = as fast as the machine allows.
        end: sim time of the gait's last callback, always passed on (None: none is).
        clock, sleep: the wall clock and a wait of so many seconds (``threading.Event.wait``
            ends the wait, and the pacing, early once its event is set).
    """

    def __init__(self, on_state, start, publish_period, dt, max_rate=None,
                 real_time_factor=0.0, end=None, clock=time.monotonic, sleep=time.sleep):
        self._on_state = on_state
        self._start = self._last_sim = float(start)
        self._publish_period = float(publish_period)
        self._tolerance = 0.5 * float(dt)
        self._min_gap = 0.0 if max_rate is None else 1.0 / max_rate
        self._factor = float(real_time_factor)
        self._end = end
        self._clock, self._sleep = clock, sleep
        self._wall_start = self._last_wall = clock()
        #: sim time between two callbacks, the simulator's ``callback_period``
        self.period = (min(self._publish_period, PACE_PERIOD) if self._factor > 0
                       else self._publish_period)

    def hold_until(self, sim_time):
        """Wait until the wall clock has caught up with ``sim_time`` (after the gait: the
        time a fallen robot takes to get up, which the simulator skips)."""
        if self._factor > 0:
            wait = self._wall_start + (sim_time - self._start) / self._factor - self._clock()
            if wait > 0 and self._sleep(wait):
                self._factor = 0.0  # the wait was ended early: the rest runs unpaced

    def __call__(self, sim_time, pose, positions, velocities):
        self.hold_until(sim_time)
        if self._end is not None and sim_time >= self._end - self._tolerance:
            self._on_state(sim_time, pose, positions, velocities)
            return
        if sim_time - self._last_sim < self._publish_period - self._tolerance:
            return
        self._last_sim = sim_time
        now = self._clock()
        if now - self._last_wall >= self._min_gap:
            self._last_wall = now
            self._on_state(sim_time, pose, positions, velocities)
