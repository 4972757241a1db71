"""The graph's Fast DDS profile without shared memory, for a process that may be stopped."""

from pathlib import Path
from xml.etree import ElementTree

from ibvs_common import dds
import pytest

NS = {'p': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}


def _user_transports(text):
    root = ElementTree.fromstring(text)
    return [t.text for t in root.iterfind('.//p:participant/p:rtps/p:userTransports/'
                                          'p:transport_id', NS)]


@pytest.fixture
def ours():
    path = dds.profiles_file()
    if path is None:
        pytest.skip('ibvs_common is not installed: no profiles file')
    return path


def test_the_derived_profile_keeps_everything_but_shared_memory(ours):
    text = ours.read_text()
    assert 'ibvs_shm' in _user_transports(text)  # else nothing is tested
    derived = dds.profile_without_shared_memory(text)
    assert _user_transports(derived) == ['ibvs_udp']
    root = ElementTree.fromstring(derived)
    assert root.findtext('.//p:heartbeatPeriod/p:nanosec', namespaces=NS) == '5000000'
    assert root.findtext('.//p:initialAnnouncements/p:count', namespaces=NS) == '20'
    assert dds.profile_without_shared_memory(derived) is None  # nothing left to take out


def test_a_profile_of_shared_memory_only_is_left_as_it_is():
    text = ('<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">'
            '<transport_descriptors><transport_descriptor><transport_id>s</transport_id>'
            '<type>SHM</type></transport_descriptor></transport_descriptors>'
            '<participant profile_name="p"><rtps><userTransports><transport_id>s'
            '</transport_id></userTransports></rtps></participant></profiles>')
    assert dds.profile_without_shared_memory(text) is None


def test_only_within_the_variable_names_the_derived_file(ours, tmp_path):
    environ = {dds.PROFILES_ENV: str(ours)}
    with dds.without_shared_memory(environ) as derived:
        assert derived
        path = Path(environ[dds.PROFILES_ENV])
        assert path != ours and _user_transports(path.read_text()) == ['ibvs_udp']
    assert environ == {dds.PROFILES_ENV: str(ours)}  # what the node processes inherit
    assert not path.exists()
    own = tmp_path / 'mine.xml'
    own.write_text(ours.read_text())
    environ = {dds.PROFILES_ENV: str(own)}
    with dds.without_shared_memory(environ) as derived:  # the user's own file: as it is
        assert not derived and environ == {dds.PROFILES_ENV: str(own)}
