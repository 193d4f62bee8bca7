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


def test_a_method_added_later_joins_the_cells_with_the_seeds_of_a_run_of_all(tmp_path):
    from archive_fixtures import tiny_archive

    archive = tiny_archive(tmp_path / 'tiny.npz')

    def campaign(out, methods, *extra, status=0):
        args = ['campaign', '--replicates', '2', '--seed', '5', '--out', str(out), '--quiet',
                '--archive', str(archive), '--methods', methods, '--goals', '0.3,0',
                '--damages', 'remove:middle_right', '--max-steps', '4',
                '--noise-std', '0.3', '--oracle-cache', str(tmp_path / 'cache'), *extra]
        proc = subprocess.run([sys.executable, '-m', 'sela_ros.experiments.cli', *args],
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == status, proc.stderr
        if status:
            return proc.stderr
        cell = cell_dir(out, archive, 'remove:middle_right', [0.3, 0.0]) / 'results.json'
        return cell, json.loads(cell.read_text())

    cell, first = campaign(tmp_path / 'a', 'oracle')
    assert list(first['methods']) == ['oracle']
    # Mark the oracle's runs: adding SELA must keep them, not run them again.
    first['methods']['oracle']['steps'] = [77, 77]
    cell.write_text(json.dumps(first))
    _, added = campaign(tmp_path / 'a', 'oracle,sela')
    assert added['methods']['oracle']['steps'] == [77, 77]
    assert set(added['summary']) == {'oracle', 'sela'}
    _, together = campaign(tmp_path / 'b', 'oracle,sela')
    assert added['methods']['sela'] == together['methods']['sela']
    # Cells run with other parameters are not read back as if they answered this command.
    for extra, named in ((['--alpha', '0.5'], 'acquisition.ucb.alpha 0.05 (asked 0.5)'),
                         (['--replicates', '3'], 'replicates 2 (asked 3)'),
                         (['--max-steps', '9'], 'max_steps 4 (asked 9)')):
        error = campaign(tmp_path / 'b', 'oracle,sela', *extra, status=2)
        assert named in error and 'Traceback' not in error
    tiny_archive(archive, seed=1)  # another map under the same name
    assert 'archive_checksum' in campaign(tmp_path / 'b', 'oracle,sela', status=2)
    assert added['parameters']['oracle_gaits_that_fall'] == \
        together['parameters']['oracle_gaits_that_fall']


def _refused(argv, capsys, monkeypatch):
    """The usage error of ``sela-experiment campaign argv``, given before any cell runs."""
    import pytest

    from sela_ros.experiments import hexapod
    from sela_ros.experiments.cli import main

    def boom(*args, **kwargs):
        raise AssertionError('a cell ran before the arguments were refused')

    monkeypatch.setattr(hexapod, 'run', boom)
    with pytest.raises(SystemExit) as exc:
        main(['campaign', '--replicates', '1', '--methods', 'sela', '--quiet', *argv])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and 'Traceback' not in err
    return err.strip().splitlines()[-1]


def test_damages_are_parsed_in_the_names_of_the_archives_robot(tmp_path, capsys, monkeypatch):
    from sela_ros.experiments import campaign
    from sela_ros.experiments.cli import build_parser
    from sim_bridge.robots import get_robot

    parser = build_parser().scenario_parsers['campaign']
    args = parser.parse_args(['--replicates', '1', '--out', str(tmp_path), '--archive', 'a1',
                              '--damages', 'block:rear_right.calf', '--goals', '1,1'])
    campaign.finish_arguments(parser, args)  # the a1's own damage is taken
    assert args.damages == [get_robot('a1').parse_damage('block:rear_right.calf').canonical()]
    error = _refused(['--out', str(tmp_path), '--archive', 'a1', '--damages',
                      'remove:front_left', '--goals', '1,1'], capsys, monkeypatch)
    assert "--damages: 'remove:front_left' on a1_archive.npz, a map of the a1" in error
    error = _refused(['--out', str(tmp_path), '--damages', 'block:rear_right.calf'], capsys,
                     monkeypatch)
    assert 'a map of the hexapod' in error and 'calf' in error


def test_every_goal_and_the_oracle_cache_are_checked_before_the_first_cell(tmp_path, capsys,
                                                                          monkeypatch):
    error = _refused(['--out', str(tmp_path / 'out'), '--damages', 'remove:front_left',
                      '--goals', '1,1', '9,9'], capsys, monkeypatch)
    assert '--goals: goal (9, 9) is off the map' in error and 'give goals on it' in error
    (tmp_path / 'file').write_text('x')
    error = _refused(['--out', str(tmp_path / 'out'), '--damages', 'remove:front_left',
                      '--goals', '1,1', '--methods', 'oracle', '--oracle-cache',
                      str(tmp_path / 'file')], capsys, monkeypatch)
    assert 'is not a directory' in error
