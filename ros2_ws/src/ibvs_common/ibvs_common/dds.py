"""
The middleware settings every process of the graph starts with (before ``rclpy.init``).

rmw_fastrtps_cpp (Jazzy's default) reads its XML profiles from the file named by
``FASTRTPS_DEFAULT_PROFILES_FILE``; ours (``share/ibvs_common/config/fastdds_profiles.xml``)
passes the stereo images through a large shared-memory segment and repairs a lost sample
within 5 ms instead of the default 3 s heartbeat, which otherwise stalls the lockstep for
seconds (the file says what was measured). A user who sets the variable keeps their own
file; other middlewares ignore it.
"""

from collections.abc import MutableMapping
import os
from pathlib import Path

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
