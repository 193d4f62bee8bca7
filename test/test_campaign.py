"""`sela-experiment campaign`: cells written as they finish, a table per damage, resumable."""
import json
import subprocess
import sys

from sela_ros.experiments.campaign import GROUPS, cell_dir, damage_list


def test_damage_list_expands_groups_and_keeps_joined_damages_whole():
    assert damage_list('single-legs') == GROUPS['single-legs']
    assert damage_list('two-legs;shorten:front_left:0.5') == [
        *GROUPS['two-legs'], 'shorten:front_left:0.5']
    assert damage_list('remove:front_left,remove:rear_right') == [
        'remove:front_left,remove:rear_right']


def _run(out):
    args = ['campaign', '--replicates', '1', '--seed', '3', '--out', str(out), '--quiet',
            '--methods', 'sela', '--damages', 'remove:middle_right;remove:front_left',
            '--goals', '0.3,0', '--max-steps', '2']
    return subprocess.run([sys.executable, '-m', 'sela_ros.experiments.cli', *args],
                          capture_output=True, text=True, timeout=600)


def test_campaign_writes_a_table_per_damage_and_resumes(tmp_path):
    proc = _run(tmp_path)
    assert proc.returncode == 0, proc.stderr
    table = (tmp_path / 'campaign.md').read_text()
    assert '## remove:middle_right' in table and '## remove:front_left' in table
    assert (tmp_path / 'figure.png').stat().st_size > 0
    doc = json.loads((tmp_path / 'results.json').read_text())
    assert [c['damage'] for c in doc['cells']] == ['remove:middle_right', 'remove:front_left']
    cell = cell_dir(tmp_path, 'hexapod_archive.npz', 'remove:front_left', [0.3, 0.0])
    steps = json.loads((cell / 'results.json').read_text())['methods']['sela']['steps']
    assert 1 <= steps[0] <= 2
    # A second run reads the cells back instead of running them again.
    (cell / 'results.json').write_text(
        (cell / 'results.json').read_text().replace('"steps": [', '"steps": [77, ', 1))
    proc = _run(tmp_path)
    assert proc.returncode == 0, proc.stderr
    rows = json.loads((tmp_path / 'results.json').read_text())['table']
    front = [r for r in rows if r['damage'] == 'remove:front_left'][0]
    assert 77 in front['steps']


def test_goals_with_negative_coordinates_are_taken_as_written_in_the_docs():
    from sela_ros.experiments.cli import build_parser

    args = build_parser().parse_args(['campaign', '--replicates', '1', '--out', 'x',
                                      '--goals', '2,2', '-2,1.5', '1.5,-2', '--kernel-sigma',
                                      '0.3'])
    assert [tuple(g) for g in args.goals] == [(2, 2), (-2, 1.5), (1.5, -2)]
    assert args.kernel_sigma == 0.3
    args = build_parser().parse_args(['hexapod', '--replicates', '1', '--out', 'x',
                                      '--goal', '-0.5,-1'])
    assert tuple(args.goal) == (-0.5, -1)
