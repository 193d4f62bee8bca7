"""Liveness from the middleware's liveliness changes: which writer is lost, which never came."""


from sela_ros.nodes.heartbeat import LivenessWatch


def test_a_lost_writer_is_reported_even_while_another_one_lives():
    watch = LivenessWatch(['planner', 'sim_bridge'], grace=2.0, now=0.0)
    assert watch.changed('planner', 1, 1, now=0.5) == 'alive'
    assert watch.check(now=1.0) == ([], [])  # sim_bridge not up yet: start-up, no alarm
    assert watch.check(now=2.5) == (['sim_bridge'], [])  # never came: silent
    assert 'never alive' in watch.why('sim_bridge', now=2.5)
    assert watch.changed('planner', 2, 1, now=3.0) is None  # a second writer (a forger's)
    assert watch.changed('planner', 1, -1, now=4.0) == 'lost'  # the planner's lease expired
    assert watch.check(now=4.1) == (['planner'], [])
    assert 'liveliness lease' in watch.why('planner', now=4.1)
    assert watch.changed('planner', 2, 1, now=5.0) == 'alive'  # restarted
    assert watch.changed('sim_bridge', 1, 1, now=5.0) == 'alive'
    assert watch.check(now=5.1) == ([], ['planner', 'sim_bridge'])
    # Between two reads a writer was lost and another came: the summed change is 0.
    assert watch.changed('planner', 2, 0, not_alive_change=1, now=6.0) == 'lost'
    assert watch.changed('planner', 1, 0, now=7.0) == 'lost'  # fewer alive than before



def test_only_a_writer_of_the_node_that_was_not_there_at_its_loss_makes_it_alive_again():
    watch = LivenessWatch(['planner'], grace=2.0, now=0.0)
    # Alive before the graph says whose the writer is: not yet; then confirmed.
    assert watch.changed('planner', 1, 1, now=0.5, writers=set()) is None
    assert watch.waiting() == ['planner']
    assert watch.confirm('planner', {'p1'}) == 'alive'
    assert watch.waiting() == []
    assert watch.changed('planner', 2, 1, now=1.0, writers={'p1'}) is None  # a forger's
    assert watch.changed('planner', 1, -1, 1, now=2.0, writers={'p1'}) == 'lost'  # killed
    # The forger destroys its writer and makes it again: the dead planner's writer, still
    # in the graph, and the forger's do not make the planner alive.
    assert watch.changed('planner', 0, -1, now=3.0, writers={'p1'}) == 'lost'
    assert watch.changed('planner', 1, 1, now=4.0, writers={'p1'}) is None
    assert watch.confirm('planner', {'p1'}) is None
    assert watch.check(now=4.5) == (['planner'], [])
    # The planner started again: a writer of its own, new.
    assert watch.changed('planner', 2, 1, now=5.0, writers={'p1', 'p2'}) == 'alive'
    assert watch.check(now=5.5) == ([], ['planner'])
    # Lost again: only a writer newer than p2 makes it alive.
    assert watch.changed('planner', 1, -1, 1, now=6.0, writers={'p2'}) == 'lost'
    assert watch.confirm('planner', {'p1', 'p2'}) is None
    assert watch.confirm('planner', {'p3'}) == 'alive'


def test_a_longer_grace_set_at_run_time_holds_the_alarm_back():
    watch = LivenessWatch(['planner'], grace=1.0, now=0.0)
    watch.set_grace(5.0)
    assert watch.check(now=2.0) == ([], [])
    assert watch.check(now=5.5) == (['planner'], [])


def test_a_writer_matched_but_never_asserted_makes_its_node_lost_until_it_asserts():
    watch = LivenessWatch(['planner'], grace=60.0, now=0.0, unasserted=5.0)
    # Matched at 1 s; a live writer asserts well within the lease: nothing to report.
    assert watch.matched('planner', 1, now=1.0) is None
    assert watch.changed('planner', 1, 1, now=2.0, writers={'p1'}, not_alive_count=0) == 'alive'
    assert watch.matched('planner', 1, now=9.0) is None
    # Killed and reported by its lease: still matched, not alive, nothing unasserted.
    assert watch.changed('planner', 0, -1, 1, now=10.0, writers={'p1'},
                         not_alive_count=1) == 'lost'
    assert watch.matched('planner', 1, now=20.0) is None
    assert 'liveliness lease' in watch.why('planner', now=20.0)
    # Restarted (p2) and killed again; a third start (p3), killed before its first
    # assertion while the node is lost, leaves it lost.
    assert watch.changed('planner', 1, 1, now=21.0, writers={'p2'}, not_alive_count=1) == 'alive'
    assert watch.check(now=21.0) == ([], [])
    assert watch.changed('planner', 0, -1, 1, now=22.0, writers={'p2'},
                         not_alive_count=2) == 'lost'
    assert watch.matched('planner', 3, now=23.0) is None  # p3 matched at 23 s...
    assert watch.matched('planner', 3, now=28.5) is None  # ... but the node is lost already
    # A node never seen: its only writer matched and never asserted.
    fresh = LivenessWatch(['planner'], grace=60.0, now=0.0, unasserted=5.0)
    assert fresh.matched('planner', 1, now=1.0) is None
    assert fresh.matched('planner', 1, now=5.9) is None
    assert fresh.matched('planner', 1, now=6.1) == 'lost'
    assert fresh.matched('planner', 1, now=7.0) is None  # said once
    assert fresh.check(now=7.0) == (['planner'], [])
    assert 'never asserted' in fresh.why('planner', now=7.0)
    # It asserts after all (a slow start): alive, and the alarm ends.
    assert fresh.changed('planner', 1, 1, now=8.0, writers={'p1'}, not_alive_count=0) == 'alive'
    assert fresh.check(now=8.0) == ([], ['planner'])
    assert fresh.matched('planner', 1, now=20.0) is None


def test_a_namesake_is_one_only_while_the_graph_and_a_live_writer_both_say_so():
    from sela_ros.nodes.heartbeat import namesake_problem

    said = namesake_problem('/planner', 2, 1, '7')
    assert '1 other node(s) named /planner' in said and 'ROS_DOMAIN_ID 7' in said
    assert 'namespace:=' in said
    # A killed namesake's entry lingers in the graph: its writer is no longer alive.
    assert namesake_problem('/planner', 2, 0, '7') is None
    # A writer of someone else's on planner/alive, no second planner: not a namesake.
    assert namesake_problem('/planner', 1, 1, '7') is None
