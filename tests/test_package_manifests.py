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
- An import inside ``try: ... except ImportError`` is optional (a feature that is off without
  it) and need not be declared.
- A runtime dependency that no runtime module imports, or a test dependency that no file
  imports, is reported: it installs something that nothing uses.

``setup.py`` is left out: it imports setuptools, which the ament_python build type brings.
"""

import ast
import importlib.metadata
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ET

import pytest

SRC = Path(__file__).resolve().parent.parent / 'ros2_ws' / 'src'

#: Python modules that are not ROS packages, and their rosdep keys as
#: ros/rosdistro rosdep/python.yaml names them (``python3-<name>-pip`` where it has only a
#: pip rule). A dotted name (ruamel.yaml) is matched before its first component.
PYTHON_KEYS = {
    'av': 'python3-av',  # PyAV
    'cv2': 'python3-opencv',
    'matplotlib': 'python3-matplotlib',
    'numpy': 'python3-numpy',
    'pybullet': 'python3-pybullet-pip',  # PyPI only
    'pytest': 'python3-pytest',
    # No rosdep key (2026-08): pip install ray; rosdep install --skip-keys python3-ray-pip.
    'ray': 'python3-ray-pip',
    'rosbags': 'python3-rosbags-pip',  # PyPI only
    'ruamel.yaml': 'python3-ruamel.yaml',
    'scipy': 'python3-scipy',
    'yaml': 'python3-yaml',
}

#: Imports that cannot be declared, (package, module): why. Each entry must still be needed.
UNDECLARABLE = {}

#: What a string constant names when it names a ROS interface type.
INTERFACE_TYPE = re.compile(r'([a-z][a-z0-9_]*)/(?:msg|srv|action)/[A-Z][A-Za-z0-9]*')

RUNTIME_TAGS = ('depend', 'exec_depend')
TEST_TAGS = ('test_depend',)


def manifest(path):
    """Return the package.xml at ``path`` as (name, build type, {tag: set of keys})."""
    root = ET.parse(path).getroot()
    build_type = root.findtext('export/build_type')
    tags = {tag: {e.text.strip() for e in root.findall(tag)} for tag in RUNTIME_TAGS + TEST_TAGS}
    return root.findtext('name'), build_type, tags


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
        required, _ = imported_modules(path.read_text(encoding='utf-8'))
        uses = tests if relative.parts[0] == 'test' else runtime
        for module in required:
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
    with pytest.raises(KeyError, match='PYTHON_KEYS'):
        rosdep_key('not_a_known_module', 'ibvs_sim')
