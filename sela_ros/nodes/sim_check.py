"""Is the archive built for the simulator that runs? Asked once per archive, never waited on.

The archive's generic rewards only mean something on a simulator with the same ``sim.dt``,
``sim.gait_duration`` and ``sim.solver_iterations``; this helper asks the simulator node for
them (its parameter service) and says whether the stepper must hold its gaits, and why.
"""
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters

from sela_ros.core.storage import SETTING_DEFAULTS, ArchiveError, check_settings

SETTINGS = ('sim.dt', 'sim.gait_duration', 'sim.solver_iterations')


class SimulatorCheck:
    """Args: node; simulator: its node name ('' on a real robot: nothing to check);
    on_hold: called with None (go), '' (asking) or the reason the archive does not match."""

    def __init__(self, node, simulator, on_hold):
        self.client = (node.create_client(GetParameters, f'{simulator}/get_parameters')
                       if simulator else None)
        self.on_hold = on_hold
        self.archive = self.source = None
        self.asked = False

    def use(self, archive, source):
        """A new archive: it gets its own check, and no gait goes out before it answers
        (a goal that comes before the simulator's parameter service is seen waits for it)."""
        self.archive, self.source, self.asked = archive, source, False
        if self.client is not None:
            self.on_hold('')

    def poll(self):
        """Ask, if not asked yet for this archive and the simulator answers requests."""
        if (self.asked or self.archive is None or self.client is None
                or not self.client.service_is_ready()):
            return
        self.asked = True
        self.on_hold('')
        archive = self.archive
        future = self.client.call_async(GetParameters.Request(names=list(SETTINGS)))
        future.add_done_callback(lambda f: self._answer(f.result(), archive))

    def _answer(self, answer, archive):
        if archive is not self.archive:
            return  # the archive changed meanwhile: it gets its own check
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
        try:
            check_settings(archive.metadata, settings, source=self.source)
        except ArchiveError as exc:
            self.on_hold(f'{exc} The simulator runs sim.dt {settings["dt"]:g} s, '
                         f'sim.gait_duration {settings["gait_duration"]:g} s, '
                         f'sim.solver_iterations {settings["solver_iterations"]}: no gait is '
                         'sent until the archive parameter names a matching archive.')
            return
        self.on_hold(None)
