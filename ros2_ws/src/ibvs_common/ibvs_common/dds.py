"""
The middleware settings every process of the graph starts with (before ``rclpy.init``).

rmw_fastrtps_cpp (Jazzy's default) reads its XML profiles from the file named by
``FASTRTPS_DEFAULT_PROFILES_FILE``; ours (``share/ibvs_common/config/fastdds_profiles.xml``)
passes the stereo images through a large shared-memory segment and repairs a lost sample
within 5 ms instead of the default 3 s heartbeat, which otherwise stalls the lockstep for
seconds (the file says why). A user who sets the variable keeps their own
file; other middlewares ignore it.

A process that may be stopped while the graph runs on (the runner: Ctrl-Z, SIGSTOP, a
debugger) takes the same profile without shared memory (:func:`without_shared_memory`):
Fast DDS's watchdog calls a shared-memory port whose listener stopped answering dead and
replaces it, and the writers of the other processes may then go on into a replaced port
that nobody reads, so that the stopped process, continued, never hears them again. Over
UDP a stopped reader only misses what its socket could not hold, and reliable delivery
catches up when it runs again.

The ROS domain is checked here too (:func:`domain_id`), by every node's ``main`` and by the
runner before anything starts: a value that rcl would read as another number, or one
outside the safe range, is refused with the variable named.
"""

from collections.abc import Iterator, MutableMapping
from contextlib import contextmanager
import os
from pathlib import Path
import re
import tempfile
from xml.etree import ElementTree

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError

PROFILES_ENV = 'FASTRTPS_DEFAULT_PROFILES_FILE'


def profiles_file() -> Path | None:
    """Return the path of the installed profiles file, or None if it is not installed."""
    try:
        path = Path(get_package_share_directory('ibvs_common')) / 'config' / \
            'fastdds_profiles.xml'
    except PackageNotFoundError:
        return None
    return path if path.is_file() else None


def configure(environ: MutableMapping[str, str] = os.environ) -> str | None:
    """Point Fast DDS at our profiles unless the user chose a file; return the one in use."""
    if PROFILES_ENV not in environ:
        path = profiles_file()
        if path is not None:
            environ[PROFILES_ENV] = str(path)
    return environ.get(PROFILES_ENV)


#: The XML namespace of Fast DDS profiles.
_PROFILES_NS = 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'


def profile_without_shared_memory(xml_text: str) -> str | None:
    """
    Return the profiles ``xml_text`` with no shared-memory transport among the user's, or None.

    The transports of type SHM are left out of every participant's ``userTransports``
    (the others, UDPv4, stay: discovery and data then go over them). None when the text
    names no such transport (the builtin transports, another file's layout): it is left as
    it is.
    """
    ElementTree.register_namespace('', _PROFILES_NS)
    ns = {'p': _PROFILES_NS}
    root = ElementTree.fromstring(xml_text)
    shm = {d.findtext('p:transport_id', namespaces=ns)
           for d in root.iterfind('.//p:transport_descriptor', ns)
           if (d.findtext('p:type', namespaces=ns) or '').strip() == 'SHM'}
    changed = False
    for transports in root.iterfind('.//p:participant/p:rtps/p:userTransports', ns):
        for tid in transports.findall('p:transport_id', ns):
            if tid.text in shm:
                transports.remove(tid)
                changed = True
        if not list(transports):
            return None  # nothing would be left to talk over
    return ElementTree.tostring(root, encoding='unicode') if changed else None


@contextmanager
def without_shared_memory(environ: MutableMapping[str, str] = os.environ) -> Iterator[bool]:
    """
    Within, point Fast DDS at the graph's profiles without shared memory; yield whether it did.

    For the ``rclpy.init`` of a process that may be stopped while the graph runs on (module
    docstring): rmw_fastrtps reads the profiles when the context's participant is made, once
    a process, and the processes started afterwards inherit the variable as it was before
    (restored on the way out, the derived file removed). A profiles file of the user's own
    (:func:`configure` did not choose it) is used as it is.
    """
    ours = profiles_file()
    path = environ.get(PROFILES_ENV)
    text = None
    if ours is not None and path == str(ours):
        text = profile_without_shared_memory(ours.read_text())
    if text is None:
        yield False
        return
    with tempfile.NamedTemporaryFile('w', suffix='.xml', prefix='ibvs_fastdds_udp_') as f:
        f.write(text)
        f.flush()
        environ[PROFILES_ENV] = f.name
        try:
            yield True
        finally:
            environ[PROFILES_ENV] = path


#: The environment variable of the ROS domain (rcl's ``RCL_DOMAIN_ID_ENV_VAR``).
DOMAIN_ENV = 'ROS_DOMAIN_ID'
#: The ROS domains ROS 2 documents as safe on Linux (inclusive): above 101 a domain's ports
#: can collide with the kernel's ephemeral ports (and from 233 on Fast DDS's port numbers
#: overflow: "port number too high").
SAFE_RANGE = (0, 101)


class DomainError(ValueError):
    """An environment variable of the ROS domain holds a value ROS must not be started with."""


def domain_id(environ: MutableMapping[str, str] = os.environ) -> int | None:
    """
    Return ``ROS_DOMAIN_ID`` as the domain ROS will use, None if unset; else DomainError.

    rcl reads the variable with ``strtoul`` (base 0): ``-1`` wraps round, ``010`` is
    octal 8, an empty value means the default domain 0. A lock taken on the text's own
    number would then not be on the domain the graph uses, so only a plain decimal number
    (no sign, no leading zero, no blank) within :data:`SAFE_RANGE` is taken; anything else,
    an empty value included, raises :class:`DomainError` naming the variable.
    """
    text = environ.get(DOMAIN_ENV)
    if text is None:
        return None
    low, high = SAFE_RANGE
    if not re.fullmatch(r'0|[1-9][0-9]{0,5}', text) or not low <= int(text) <= high:
        raise DomainError(
            f'{DOMAIN_ENV}={text!r} is not a ROS domain this graph can use: expected a '
            f'decimal number from {low} to {high} (the domains ROS 2 documents as safe on '
            f'Linux), or {DOMAIN_ENV} unset to take the first free domain')
    return int(text)
