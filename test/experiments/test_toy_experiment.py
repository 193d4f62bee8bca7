"""The sela-experiment CLI: results schema, figure, argument errors (exit code 2)."""
import json
import subprocess
import sys

import pytest

from sela_ros.experiments.cli import main


def test_toy_writes_schema(tmp_path):
    out = tmp_path / 'toy'
    assert main(['toy', '--replicates', '3', '--seed', '5', '--out', str(out),
                 '--noise-std', '0.01', '--quiet']) == 0
    doc = json.loads((out / 'results.json').read_text())
    assert doc['scenario'] == 'toy' and doc['replicates'] == 3
    assert list(doc['methods']) == ['sela', 'random_babbling', 'ite_4dir', 'oracle']
    for m in doc['methods'].values():
        assert set(m) == {'success', 'steps', 'learning_iterations'}
        assert len(m['success']) == len(m['steps']) == len(m['learning_iterations']) == 3
        assert all(isinstance(s, bool) for s in m['success'])
        assert all(isinstance(s, int) for s in m['steps'] + m['learning_iterations'])
    assert doc['methods']['sela']['success'] == [True] * 3
    assert doc['methods']['oracle']['steps'] == [28] * 3
    assert (out / 'figure.png').stat().st_size > 1000
    # Same seed, same results; with 2 workers too.
    out2 = tmp_path / 'toy2'
    main(['toy', '--replicates', '3', '--seed', '5', '--out', str(out2), '--noise-std',
          '0.01', '--quiet', '--workers', '2'])
    assert json.loads((out2 / 'results.json').read_text())['methods'] == doc['methods']


@pytest.mark.parametrize('args', [
    [],
    ['toy'],
    ['toy', '--replicates', '0', '--out', 'x'],
    ['toy', '--replicates', 'two', '--out', 'x'],
    ['toy', '--replicates', '2', '--out', 'x', '--noise-std', '-1'],
    ['toy', '--replicates', '2', '--out', 'x', '--methods', 'sela,nope'],
    ['toy', '--replicates', '2', '--out', 'x', '--seed', '-3'],
    ['hexapod_unknown', '--replicates', '2', '--out', 'x'],
])
def test_bad_arguments_exit_2_without_traceback(args, tmp_path):
    proc = subprocess.run([sys.executable, '-m', 'sela_ros.experiments.cli', *args],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120,
                          env={'PYTHONPATH': str(__import__('pathlib').Path(__file__)
                                                 .resolve().parents[2])})
    assert proc.returncode == 2
    assert 'usage:' in proc.stderr and 'Traceback' not in proc.stderr


def test_out_is_a_file(tmp_path, capsys):
    f = tmp_path / 'file'
    f.write_text('x')
    with pytest.raises(SystemExit) as exc:
        main(['toy', '--replicates', '1', '--out', str(f)])
    assert exc.value.code == 2
    err = capsys.readouterr().err  # said with the scenario's usage
    assert err.startswith('usage: sela-experiment toy ') and 'sela-experiment toy: error' in err


def test_an_unexpected_error_of_a_scenario_comes_through_as_itself(tmp_path, monkeypatch):
    """Only the scenario's own argument errors become exit 2; anything else is raised as
    it is (before, the toy scenario's lack of ``CellMismatch`` turned it into a TypeError
    of the except clause)."""
    from sela_ros.experiments import toy

    def broken(args, progress):
        raise RuntimeError('the simulator broke')

    monkeypatch.setattr(toy, 'run', broken)
    with pytest.raises(RuntimeError, match='the simulator broke'):
        main(['toy', '--replicates', '1', '--quiet', '--out', str(tmp_path / 'out')])


def test_noise_beyond_the_nodes_range_is_a_usage_error_and_noise_within_it_a_run(tmp_path,
                                                                                  capsys):
    base = ['toy', '--replicates', '2', '--max-steps', '5', '--quiet', '--methods', 'sela']
    for noise in ('1.5', '100', '1e300'):
        with pytest.raises(SystemExit) as exc:
            main([*base, '--out', str(tmp_path / 'refused'), '--noise-std', noise])
        assert exc.value.code == 2
        assert 'at most 1 m' in capsys.readouterr().err
    # 1 m: most outcomes are implausible (refused, as the node refuses them), yet it runs.
    assert main([*base, '--out', str(tmp_path / 'noisy'), '--noise-std', '1']) == 0
    doc = json.loads((tmp_path / 'noisy' / 'results.json').read_text())
    assert doc['parameters']['noise_std'] == 1.0 and len(doc['methods']['sela']['steps']) == 2


def test_methods_are_each_run_once_and_none_is_said_as_such(tmp_path, capsys):
    from sela_ros.experiments.arguments import method_list

    assert method_list('sela,oracle,sela') == ['sela', 'oracle']
    for text in ('', ' , '):
        with pytest.raises(SystemExit) as exc:
            main(['toy', '--replicates', '1', '--out', str(tmp_path), '--methods', text])
        assert exc.value.code == 2
        assert 'expected at least one method' in capsys.readouterr().err
    assert main(['toy', '--replicates', '2', '--max-steps', '3', '--quiet', '--out',
                 str(tmp_path / 'twice'), '--methods', 'sela,sela']) == 0
    doc = json.loads((tmp_path / 'twice' / 'results.json').read_text())
    assert list(doc['methods']) == ['sela'] and len(doc['methods']['sela']['steps']) == 2
