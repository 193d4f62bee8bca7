"""DDS stays on loopback: the environment applies the profile, and the profile allows loopback
transports only (every socket of every process: dds/test_loopback_sockets.py)."""
import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from sela_ros.tools.ros_env import LOOPBACK_PROFILE, PACKAGE, loopback_profile, ros_environment

NS = {'dds': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}


def test_the_environment_applies_the_loopback_profile():
    """The profile of the ament prefix in use (``make venv``'s .venv, or a colcon install
    whose tests import the package from the source tree), and with no prefix given, the
    first one found from the interpreter's."""
    from ament_index_python.packages import get_package_share_directory

    installed = Path(get_package_share_directory(PACKAGE)) / 'config' / LOOPBACK_PROFILE
    prefix = {'AMENT_PREFIX_PATH': os.environ['AMENT_PREFIX_PATH']}
    for base, expected in ((prefix, installed), ({}, loopback_profile(sys.prefix))):
        env = ros_environment(domain_id=42, base=base)
        assert env['FASTDDS_DEFAULT_PROFILES_FILE'] == env['FASTRTPS_DEFAULT_PROFILES_FILE']
        assert env['FASTDDS_DEFAULT_PROFILES_FILE'] == str(expected), base
        assert Path(env['FASTDDS_DEFAULT_PROFILES_FILE']).is_file()
        # The one range in which the rmw leaves the profile's transports and locators alone.
        assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SYSTEM_DEFAULT'
        assert env['RMW_IMPLEMENTATION'] == 'rmw_fastrtps_cpp' and env['ROS_DOMAIN_ID'] == '42'


def test_the_profile_is_the_installed_one_or_the_source_trees():
    """On a ROS install (``colcon test``) the profile is the one the package installed, found
    through the ament index; in a source checkout it may be the source tree's."""
    from ament_index_python.packages import get_package_share_directory

    installed = Path(get_package_share_directory(PACKAGE)) / 'config' / LOOPBACK_PROFILE
    source = Path(__file__).resolve().parents[2] / 'config' / LOOPBACK_PROFILE
    assert installed.is_file()
    assert loopback_profile() in (installed, source)
    # An environment with no ament prefix at all still finds it (the module's own prefix).
    assert loopback_profile(os.devnull) in (installed.resolve(), source)


def test_the_profile_allows_loopback_transports_only():
    root = ET.parse(loopback_profile()).getroot()
    participant = root.find('.//dds:participant', NS)
    assert participant.get('is_default_profile') == 'true'
    rtps = participant.find('dds:rtps', NS)
    assert rtps.findtext('dds:useBuiltinTransports', namespaces=NS) == 'false'
    used = {t.text for t in rtps.findall('dds:userTransports/dds:transport_id', NS)}
    for descriptor in root.findall('.//dds:transport_descriptor', NS):
        if descriptor.findtext('dds:transport_id', namespaces=NS) not in used:
            continue
        kind = descriptor.findtext('dds:type', namespaces=NS)
        assert kind in ('UDPv4', 'SHM'), kind
        if kind == 'UDPv4':
            allowed = [a.text for a in descriptor.findall('dds:interfaceWhiteList/*', NS)]
            assert allowed == ['127.0.0.1']
    addresses = [a.text for a in rtps.findall('.//dds:locator/dds:udpv4/dds:address', NS)]
    assert addresses and set(addresses) == {'127.0.0.1'}


