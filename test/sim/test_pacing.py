"""A gait held to the wall clock (``real_time_factor``) and its state messages spaced."""
import threading

import pytest

from sim_bridge.pacing import PACE_PERIOD, GaitPace


class FakeWall:
    """A wall clock that moves only when told to, or when slept on."""

    def __init__(self):
        self.now = 100.0
        self.slept = []

    def __call__(self):
        return self.now

    def sleep(self, seconds):
        self.slept.append(seconds)
        self.now += seconds


def _run(pace, start, duration, dt, cost=0.0, wall=None):
    """Calls ``pace`` as the simulator does, every ``pace.period``; each physics step
    costs ``cost`` wall seconds."""
    every = max(1, round(pace.period / dt))
    n = round(duration / dt)
    for k in range(n):
        if wall is not None:
            wall.now += cost
        if (k + 1) % every == 0 or k + 1 == n:
            pace(start + (k + 1) * dt, (0.0, 0.0, 0.0), [], [])


def test_unpaced_gait_publishes_every_period_and_never_waits():
    wall, seen = FakeWall(), []
    pace = GaitPace(lambda t, *_: seen.append(t), 10.0, 0.5, 1 / 240, clock=wall,
                    sleep=wall.sleep)
    assert pace.period == 0.5
    _run(pace, 10.0, 3.0, 1 / 240, cost=0.001, wall=wall)
    assert wall.slept == []
    assert seen == pytest.approx([10.5, 11.0, 11.5, 12.0, 12.5, 13.0])


@pytest.mark.parametrize('factor', [1.0, 0.5, 4.0])
def test_paced_gait_lasts_its_sim_time_over_the_factor(factor):
    wall, seen = FakeWall(), []
    pace = GaitPace(lambda t, *_: seen.append(t), 0.0, 0.5, 1 / 240, real_time_factor=factor,
                    clock=wall, sleep=wall.sleep)
    assert pace.period == PACE_PERIOD  # finer than the messages: the pace is held smoothly
    start = wall.now
    _run(pace, 0.0, 3.0, 1 / 240, cost=1e-5, wall=wall)
    assert wall.now - start == pytest.approx(3.0 / factor, abs=1e-6)
    every = round(PACE_PERIOD * 240) / 240  # the callback period in whole physics steps
    assert max(wall.slept) <= every / factor + 1e-9
    # the messages as unpaced: every publish_period of sim time
    assert seen == pytest.approx([0.5, 1.0, 1.5, 2.0, 2.5, 3.0], abs=1e-9)


def test_a_gait_slower_than_the_factor_is_not_held_back():
    wall = FakeWall()
    pace = GaitPace(lambda *_: None, 0.0, 0.5, 0.01, real_time_factor=1.0, clock=wall,
                    sleep=wall.sleep)
    _run(pace, 0.0, 1.0, 0.01, cost=0.02, wall=wall)  # the physics alone: half real time
    assert wall.slept == []


def test_the_rate_cap_drops_messages_but_never_the_end():
    wall, seen = FakeWall(), []
    pace = GaitPace(lambda t, *_: seen.append(t), 0.0, 0.1, 0.01, max_rate=1.0, end=1.0,
                    clock=wall, sleep=wall.sleep)
    _run(pace, 0.0, 1.0, 0.01, cost=0.051, wall=wall)  # 0.51 wall s per 0.1 sim s
    # at most one a wall second: every other message, and the end whatever the cap
    assert seen == pytest.approx([0.2, 0.4, 0.6, 0.8, 1.0])


def test_an_ended_wait_stops_the_pacing():
    stop = threading.Event()
    stop.set()  # shutting down: the gait finishes at once
    wall = FakeWall()
    pace = GaitPace(lambda *_: None, 0.0, 0.5, 0.01, real_time_factor=0.1, clock=wall,
                    sleep=stop.wait)
    _run(pace, 0.0, 3.0, 0.01)
    assert wall.now == 100.0


def test_the_time_a_fallen_robot_takes_to_get_up_is_held_too():
    wall = FakeWall()
    pace = GaitPace(lambda *_: None, 0.0, 0.5, 0.01, real_time_factor=2.0, clock=wall,
                    sleep=wall.sleep)
    start = wall.now
    _run(pace, 0.0, 3.0, 0.01)
    pace.hold_until(6.0)  # the simulator skipped 3 s of sim time: the robot getting up
    assert wall.now - start == pytest.approx(3.0)
    unpaced = GaitPace(lambda *_: None, 0.0, 0.5, 0.01, clock=wall, sleep=wall.sleep)
    unpaced.hold_until(6.0)
    assert wall.now - start == pytest.approx(3.0)
