"""Launch actions the package's launch files share (``ros2 launch`` imports them from here)."""
from sela_ros.nodes.node_main import EXIT_BAD_CONFIGURATION


def refused_configuration_reason(process_name, returncode):
    """Why the launch ends when ``process_name`` exited with ``returncode``; None when it
    goes on: only a node that refused its configuration (a bad parameter, a malformed params
    file, an archive it cannot use: its one-line error is just above) ends it. A node that
    crashed or was killed leaves the others running, as its heartbeat's watchers say."""
    if returncode != EXIT_BAD_CONFIGURATION:
        return None
    return (f'{process_name} refused its configuration (exit {returncode}; its error is '
            'above): the stack cannot run without it')


def end_on_refused_configuration():
    """A ``RegisterEventHandler`` ending the launch once a node refuses its configuration,
    rather than leaving the rest of the stack up without it."""
    from launch.actions import EmitEvent, LogInfo, RegisterEventHandler
    from launch.event_handlers import OnProcessExit
    from launch.events import Shutdown

    def on_exit(event, context):
        reason = refused_configuration_reason(event.process_name, event.returncode)
        if reason is None:
            return None
        return [LogInfo(msg=reason), EmitEvent(event=Shutdown(reason=reason))]

    return RegisterEventHandler(OnProcessExit(on_exit=on_exit))
