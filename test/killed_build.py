"""Kill a map build the hard way once it has something to resume from (tests of resuming)."""
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest


def sigkill_once_journalled(cmd, ckpt, cwd, env, wait=180.0):
    """Start the build ``cmd`` and SIGKILL it once its checkpoint ``ckpt`` and at least one
    journalled batch after it exist (within ``wait`` seconds); returns its exit code."""
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    journal = Path(str(ckpt) + '.journal')
    deadline = time.monotonic() + wait
    while time.monotonic() < deadline:
        if Path(ckpt).exists() and journal.is_dir() and any(journal.glob('batch_*.npz')):
            break
        assert proc.poll() is None, 'the run ended before it could be killed'
        time.sleep(0.01)
    else:
        proc.kill()
        pytest.fail(f'no checkpoint within {wait:g} s')
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    return proc.returncode
