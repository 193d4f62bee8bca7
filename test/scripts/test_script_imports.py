"""Every script of the repository runs the repository's own sela_ros (and so do the worker
processes it starts, which import what the script imported): a copy installed in the
environment (``make venv`` installs one) would otherwise answer for the tree a developer has
just edited."""
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Scripts that run the installed copy on purpose, and why.
INSTALLED = {'compare_product.py': 'it runs the installed nodes (sela-demo) beside the '
                                   'experiment runner: both halves must be the same copy'}
SCRIPTS = sorted(p for p in (ROOT / 'scripts').glob('*.py')
                 if 'sela_ros' in p.read_text() and p.name not in INSTALLED)

# Run as `python scripts/<name>.py --help` runs it: the script's folder first on sys.path, not
# the working directory (-P); which sela_ros it imported, if any, printed at the end.
_RUN = '''
import runpy, sys
path = sys.argv[1]
sys.argv = [path, '--help']
sys.path.insert(0, str(__import__('pathlib').Path(path).parent))
try:
    runpy.run_path(path, run_name='__main__')
except SystemExit:
    pass
module = sys.modules.get('sela_ros')
print('SELA_ROS_FROM', module.__file__ if module else None)
'''


@pytest.mark.parametrize('script', SCRIPTS, ids=lambda p: p.name)
def test_a_script_imports_the_tree_it_is_in(script, tmp_path):
    out = subprocess.run([sys.executable, '-P', '-c', _RUN, str(script)], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    line = [x for x in out.stdout.splitlines() if x.startswith('SELA_ROS_FROM')]
    assert line, (out.stdout[-2000:], out.stderr[-2000:])
    where = line[-1].split(' ', 1)[1]
    if where != 'None':
        assert Path(where).resolve().is_relative_to(ROOT / 'sela_ros'), where

