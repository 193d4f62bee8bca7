"""SELA's markers, /tf and /robot_description go into an MCAP that decodes back (Foxglove
reads the same), and the picture in docs/ can be drawn from it."""
import math

import pytest
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from sela_ros.nodes.markers import decision_markers, outcome_markers


def _decision(step=0):
    candidates = [(0.3 + 0.01 * i, 0.2, 0.05 * (i + 1), -0.1 * i) for i in range(4)]
    return decision_markers('odom', 3.0 * step, (0.1 * step, 0.0, 0.0), (0.5, 0.5),
                            candidates, (0.3, 0.2), 0.05)


@pytest.mark.dds
def test_mcap_holds_tf_description_and_markers_and_draws_them(tmp_path):
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    from sela_ros.nodes.interface import LATCHED_QOS
    from sela_ros.tools.mcap_figure import draw, read_recording
    from sela_ros.tools.recording import McapRecorder

    from ros_graph import Client

    sender, recorder_client = Client('markers_sender'), Client('markers_recorder')
    path = tmp_path / 'mission.mcap'
    topics = {'/tf': TFMessage, '/robot_description': String, '/sela/markers': MarkerArray}
    recorder = McapRecorder(recorder_client.node, str(path), topics,
                            qos_for=lambda t: LATCHED_QOS if 'description' in t else 10)
    try:
        tf_pub = sender.node.create_publisher(TFMessage, '/tf', 10)
        description_pub = sender.node.create_publisher(String, '/robot_description',
                                                       LATCHED_QOS)
        markers_pub = sender.node.create_publisher(MarkerArray, '/sela/markers', 10)
        # Matched on both sides: the recorder sees the publishers and each publisher its
        # subscription (a volatile message sent before that is lost: seen under load).
        pubs = (tf_pub, description_pub, markers_pub)
        recorder_client.spin_until(
            lambda: all(recorder_client.node.count_publishers(t) for t in topics)
            and all(p.get_subscription_count() for p in pubs), 30, 'the publishers')
        description_pub.publish(String(data='<robot name="sela_hexapod"/>'))
        steps = 3
        for step in range(steps):
            tf = TransformStamped()
            tf.header.frame_id, tf.child_frame_id = 'odom', 'base_link'
            tf.transform.translation.x = 0.1 * step
            tf.transform.rotation.w = 1.0
            tf_pub.publish(TFMessage(transforms=[tf]))
            markers_pub.publish(_decision(step))
            markers_pub.publish(outcome_markers('odom', 3.0 * step + 3, (0.1 * step + 0.2, 0.1),
                                                [(0, 0), (0.2, 0.1)]))
        recorder_client.spin_until(
            lambda: recorder.counts['/sela/markers'] == 2 * steps
            and recorder.counts['/tf'] == steps and recorder.counts['/robot_description'],
            30, 'every message recorded')
    finally:
        recorder.close()
        sender.close()
        recorder_client.close()
    recording = read_recording(str(path))
    assert recording['description'] == '<robot name="sela_hexapod"/>'
    assert [x for _, x, _ in recording['tf']] == pytest.approx([0.0, 0.1, 0.2])
    assert len(recording['steps']) == steps
    for step in recording['steps']:
        assert step['waypoint'] == (0.5, 0.5) and len(step['candidates']) == 4
        assert step['observed'] is not None and math.isclose(step['observed'][1], 0.1)
    png = draw(recording, tmp_path / 'markers.png')
    assert png.stat().st_size > 10_000
