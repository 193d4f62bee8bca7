"""When the sela_adapter's archive may change (no DDS: the checks over a stand-in node)."""
from types import SimpleNamespace

import numpy as np

from sela_ros.core import stepper_io as io
from sela_ros.core.archive_paths import default_archive_path
from sela_ros.nodes import adapter_support


class _Logger:
    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(text)


def _node(state, learned=0):
    stepper = SimpleNamespace(state=state,
                              sela=SimpleNamespace(observations=(np.zeros(learned),)))
    logger = _Logger()
    return SimpleNamespace(archive=object(), archive_path='/nowhere/in_use.npz',
                           stepper=stepper, get_logger=lambda: logger,
                           get_name=lambda: 'sela_adapter')


def test_a_file_that_cannot_be_loaded_is_refused_for_its_problem_even_mid_step(tmp_path):
    broken = tmp_path / 'broken.npz'
    broken.write_bytes(b'PK\x03\x04 truncated')
    for state in io.State:
        reason = adapter_support.archive_change(_node(state, learned=3), str(broken))
        assert reason is not None and 'broken.npz' in reason, (state, reason)
        assert 'mid-step' not in reason and 'learned' not in reason


def test_a_good_file_is_refused_mid_step_and_while_something_is_learned():
    good = str(default_archive_path())
    for state in (io.State.PLANNING, io.State.EXECUTING, io.State.VERDICT,
                  io.State.RESETTING):
        reason = adapter_support.archive_change(_node(state), good)
        assert 'mid-step' in reason and 'between steps' in reason, (state, reason)
    reason = adapter_support.archive_change(_node(io.State.IDLE, learned=2), good)
    assert '2 observation(s)' in reason and 'sela_adapter/clear' in reason
