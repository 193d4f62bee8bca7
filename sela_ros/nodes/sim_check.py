"""Is the archive built for the simulator that runs? Asked once per archive, never waited on;
a question not answered within :data:`ANSWER_TIMEOUT` (a response DDS lost) is asked again.

The archive's generic rewards only mean something on a simulator with the same ``sim.dt``,
``sim.gait_duration`` and ``sim.solver_iterations``; this helper asks the simulator node for
them (its parameter service) and says whether the stepper must hold its gaits, and why.
"""
import time

from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters

from sela_ros.core.storage import SETTING_DEFAULTS, ArchiveError, check_settings

SETTINGS = ('sim.dt', 'sim.gait_duration', 'sim.solver_iterations')
#: s (wall) to wait for the simulator's answer before asking again.
ANSWER_TIMEOUT = 5.0


class SimulatorCheck:
    """Args: node; simulator: its node name ('' on a real robot: nothing to check);
    on_hold: called with None (go), '' (asking) or the reason the archive does not match."""

    def __init__(self, node, simulator, on_hold):
        self.client = (node.create_client(GetParameters, f'{simulator}/get_parameters')
                       if simulator else None)
        self.on_hold = on_hold
        self.logger = node.get_logger()
        self.archive = self.source = None
        self.settings = None  # the simulator's, once it answered
        self.asked = False
        self._pending = None  # the question not answered yet, and when it was asked
        self._asked_at = 0.0

    def use(self, archive, source):
        """A new archive: it gets its own check, and no gait goes out before it answers
        (a goal that comes before the simulator's parameter service is seen waits for it)."""
        self.archive, self.source, self.asked = archive, source, False
        self._forget_pending()
        if self.client is not None:
            self.on_hold('')

    def poll(self):
        """Ask, if not asked yet for this archive (or asked and not answered within
        :data:`ANSWER_TIMEOUT`) and the simulator answers requests."""
        if self.archive is None or self.client is None:
            return
        if self.asked:
            if self._pending is None or time.monotonic() - self._asked_at < ANSWER_TIMEOUT:
                return
            self.logger.warn(f'{self.client.srv_name}: no answer in {ANSWER_TIMEOUT:g} s, '
                             'asking again')
            self._forget_pending()
        if not self.client.service_is_ready():
            return
        self.asked = True
        self.on_hold('')
        archive = self.archive
        future = self.client.call_async(GetParameters.Request(names=list(SETTINGS)))
        self._pending, self._asked_at = future, time.monotonic()
        future.add_done_callback(lambda f: self._answer(f, archive))

    def _forget_pending(self):
        if self._pending is not None:
            self.client.remove_pending_request(self._pending)  # a late answer is dropped
            self._pending = None

    def _answer(self, future, archive):
        if future is not self._pending or archive is not self.archive:
            return  # asked again since, or the archive changed: it gets its own check
        self._pending = None
        answer = future.result()
        values = answer.values if answer is not None else []
        if len(values) != 3 or any(v.type != ParameterType.PARAMETER_DOUBLE
                                   for v in values[:2]):
            self.asked = False  # not a simulator we know how to ask: try again later
            self.on_hold(None)
            return
        settings = {'dt': values[0].double_value, 'gait_duration': values[1].double_value}
        # A simulator without the parameter predates it: it runs the old default.
        settings['solver_iterations'] = (
            values[2].integer_value if values[2].type == ParameterType.PARAMETER_INTEGER
            else SETTING_DEFAULTS['solver_iterations'])
        self.settings = settings
        problem = self.mismatch(archive, self.source)
        self.on_hold(None if problem is None else
                     f'{problem}: no gait is sent until the archive parameter names a '
                     'matching archive.')

    def mismatch(self, archive, source):
        """Why ``archive`` (read from ``source``) does not match the simulator's physics as
        it last answered, or None (it matches, or the simulator has not answered yet)."""
        if self.settings is None:
            return None
        settings = self.settings
        try:
            check_settings(archive.metadata, settings, source=source)
        except ArchiveError as exc:
            return (f'{exc} The simulator runs sim.dt {settings["dt"]:g} s, '
                    f'sim.gait_duration {settings["gait_duration"]:g} s, '
                    f'sim.solver_iterations {settings["solver_iterations"]}')
        return None
