"""Draw what a recorded mission shows in Foxglove, from the MCAP alone.

Decodes the recording (``mcap-ros2-support``, with the schemas stored in the file: no ROS
install needed) and draws, seen from above: the body's path from ``/tf`` (odom ->
base_link), and SELA's markers of every step (waypoint, the top-K candidates' predicted
landing discs of diameter 2 sigma, the chosen gait's arrow, where the robot really went).

Usage: ``python -m sela_ros.tools.mcap_figure out/demo/mission.mcap docs/sela_markers.png``
"""
import argparse
import sys


def read_recording(path, tf_topic='/tf', markers_topic='/sela/markers'):
    """``{'tf': [(t, x, y)], 'steps': [dict], 'description': str or None}`` from an MCAP.

    Each step dict holds what one decision's markers said: ``waypoint`` (x, y),
    ``candidates`` [(x, y, diameter)], ``chosen`` ((x0, y0), (x1, y1)), and ``observed``
    (x, y) once its outcome came.
    """
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    tf, steps, description = [], [], None
    with open(path, 'rb') as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        for _, channel, message, msg in reader.iter_decoded_messages():
            if channel.topic == tf_topic:
                for t in msg.transforms:
                    if t.child_frame_id == 'base_link':
                        tr = t.transform.translation
                        tf.append((message.log_time * 1e-9, tr.x, tr.y))
            elif channel.topic.endswith('robot_description'):
                description = msg.data
            elif channel.topic == markers_topic:
                _add_markers(steps, msg.markers)
    return {'tf': tf, 'steps': steps, 'description': description}


def _add_markers(steps, markers):
    namespaces = {m.ns for m in markers}
    if 'waypoint' in namespaces:  # a decision: a new step
        steps.append({'candidates': [], 'observed': None})
    if not steps:
        return
    step = steps[-1]
    for m in markers:
        p = m.pose.position
        if m.ns == 'waypoint':
            step['waypoint'] = (p.x, p.y)
        elif m.ns == 'candidates':
            step['candidates'].append((p.x, p.y, m.scale.x))
        elif m.ns == 'chosen' and len(m.points) == 2:
            step['chosen'] = ((m.points[0].x, m.points[0].y), (m.points[1].x, m.points[1].y))
        elif m.ns == 'observed' and m.type == 2:  # SPHERE: the end of this step's gait
            step['observed'] = (p.x, p.y)


def draw(recording, out_path, title='SELA, as recorded', focus=None):
    """Two panels: the whole mission, and one step up close (``focus``, 1-based; default:
    the step whose candidates the GPs are surest of), candidates as discs of 2 sigma."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    steps = recording['steps']
    if focus is None and steps:
        focus = 1 + min(range(len(steps)), key=lambda i: sum(
            c[2] for c in steps[i]['candidates']) or float('inf'))
    fig, (whole, close) = plt.subplots(1, 2, figsize=(12, 6))
    if recording['tf']:
        _, xs, ys = zip(*recording['tf'])
        whole.plot(xs, ys, color='0.3', lw=1.2, label='body (/tf odom -> base_link)')
    for i, step in enumerate(steps):
        first = i == 0
        if step['candidates']:
            cx, cy, _ = zip(*step['candidates'])
            whole.plot(cx, cy, '.', color='tab:blue', ms=3, alpha=0.5,
                       label='top candidates by UCB (predicted landing)' if first else None)
        _draw_step(whole, step, first)
    whole.set_title(f'{title}: {len(steps)} steps')
    if focus:
        step = steps[focus - 1]
        for x, y, diameter in step['candidates']:
            close.add_patch(Circle((x, y), diameter / 2, color='tab:blue', alpha=0.15, lw=0))
            close.add_patch(Circle((x, y), diameter / 2, fill=False, color='tab:blue', lw=0.8))
            close.plot(x, y, '.', color='tab:blue', ms=5)
        _draw_step(close, step, True)
        close.plot([], [], color='tab:blue', label='candidate: disc of 2 sigma')
        close.set_title(f'step {focus}: the candidates and their uncertainty')
        close.autoscale_view()
    for ax in (whole, close):
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_xlabel('x (m, odom)')
        ax.set_ylabel('y (m, odom)')
        ax.grid(alpha=0.3)
        ax.legend(loc='best', fontsize=8)
    fig.tight_layout()
    fig.savefig(out_path, dpi=100)
    plt.close(fig)
    return out_path


def _draw_step(ax, step, label):
    if 'chosen' in step:
        (x0, y0), (x1, y1) = step['chosen']
        ax.annotate('', (x1, y1), (x0, y0),
                    arrowprops={'arrowstyle': '->', 'color': 'tab:orange', 'lw': 1.4})
        if label:
            ax.plot([], [], color='tab:orange', label='chosen gait (predicted)')
    if 'waypoint' in step:
        ax.plot(*step['waypoint'], 'o', color='m', ms=5, label='waypoint' if label else None)
    if step['observed'] is not None:
        ax.plot(*step['observed'], 'o', color='tab:green', ms=5,
                label='observed end' if label else None)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('mcap', help='recording (e.g. out/demo/mission.mcap)')
    parser.add_argument('png', help='picture to write')
    args = parser.parse_args(argv)
    recording = read_recording(args.mcap)
    if not recording['steps']:
        print(f'mcap_figure: no SELA markers in {args.mcap}', file=sys.stderr)
        return 1
    draw(recording, args.png)
    print(f'wrote {args.png}: {len(recording["steps"])} steps, {len(recording["tf"])} '
          'transforms')
    return 0


if __name__ == '__main__':
    sys.exit(main())
