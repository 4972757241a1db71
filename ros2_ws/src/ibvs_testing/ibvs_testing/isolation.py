"""
Each test process on its own ROS domain, with discovery on localhost only.

Nothing happens on import: the repository's root ``conftest.py`` calls :func:`isolate` from
its ``pytest_configure`` hook, in the controlling pytest process and in each pytest-xdist
worker, before any test module is collected.
"""

import os
from typing import MutableMapping

#: Environment variable that says the process's ROS domain was chosen by :func:`isolate`.
DOMAIN_SET_BY = 'IBVS_TEST_DOMAIN_SET_BY'


def isolate(environ: MutableMapping[str, str] = os.environ) -> int:
    """
    Give this test process its own ROS domain and keep discovery on localhost.

    Parallel test runs (two CI jobs, a developer's shell, other agents' graphs) must not
    hear each other. An explicit ``ROS_DOMAIN_ID`` in the environment wins.

    Under pytest-xdist (``make test`` runs two workers) the workers inherit the environment
    of the controlling pytest process, which set its own domain here: each worker then takes
    a domain of its own (:data:`DOMAIN_SET_BY` marks a domain chosen here, not by the
    user), else the workers' nodes would hear each other and their graph runs would contend
    for one domain's lock. Calling it again in the same process changes nothing.

    Parameters
    ----------
    environ : mutable mapping of str to str
        The environment to set (the process's own by default).

    Returns
    -------
    int
        The ROS domain of this process.

    """
    worker = environ.get('PYTEST_XDIST_WORKER', '')
    chosen_here = environ.get(DOMAIN_SET_BY) == 'isolate'
    if 'ROS_DOMAIN_ID' not in environ or (worker and chosen_here):
        index = int(worker[2:]) if worker.startswith('gw') and worker[2:].isdigit() else 0
        # 1..100: inside the range ROS 2 documents as safe on Linux; two workers (gw0, gw1)
        # of one run get neighbouring domains.
        environ['ROS_DOMAIN_ID'] = str(1 + (2 * (os.getppid() % 50) + index) % 100
                                       if worker else 1 + os.getpid() % 100)
        environ[DOMAIN_SET_BY] = 'isolate'
    environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return int(environ['ROS_DOMAIN_ID'])


def domain_id_of_process() -> int:
    """Return the ROS domain of this test process (``ROS_DOMAIN_ID``, set by :func:`isolate`)."""
    return int(os.environ['ROS_DOMAIN_ID'])
