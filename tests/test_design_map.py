"""
docs/design.md §2's map names every package under ros2_ws/src and every module in it.

The map is the page's first code block under "## 2. Layout": a package at two spaces
(``  ibvs_model/``), its modules below it at four (``    robot.py``), a subpackage's
folder at four (``    detector/``) with its modules at six. Every ``ibvs_*`` package and
every Python module of its Python package (not ``__init__.py``; its tests and setup.py lie
outside it) must be named, and nothing the map names may be missing from the tree: a module
added, moved or removed without its line is caught here, not by a reader. Pure Python.
"""

from pathlib import Path
import re

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / 'docs' / 'design.md'
SRC = ROOT / 'ros2_ws' / 'src'
#: A map line that names a package, or a folder or module inside one, and its indentation.
ENTRY = re.compile(r'^( *)([A-Za-z_][\w.]*(?:/|\.py))(?=\s|$)')


def design_map(text):
    """
    Return what §2's map names: the packages and each one's module paths.

    Parameters
    ----------
    text : str
        The Markdown source of docs/design.md.

    Returns
    -------
    dict of str to set of str
        Each ``ibvs_*`` package the map names, with the paths of the modules listed under
        it, relative to its Python package (``detector/stereo.py``).

    """
    section = text.split('\n## 2. Layout\n', 1)[1].split('\n## ', 1)[0]
    block = section.split('```', 2)[1]
    named, package, folders = {}, None, {}
    for line in block.splitlines():
        match = ENTRY.match(line)
        # A description's next line is indented further than any entry: not an entry.
        if match is None or len(match.group(1)) > 2 * (len(folders) + 2):
            continue
        depth, name = (len(match.group(1)) - 2) // 2, match.group(2)
        if depth < 0:  # ros2_ws/src/ itself, or a folder beside it (tests/, docs/)
            package = None
        elif depth == 0:  # a package, or another folder of ros2_ws/src
            package = name[:-1] if name.startswith('ibvs_') and name.endswith('/') else None
            if package is not None:
                named[package], folders = set(), {}
        elif package is not None:
            folders = {d: f for d, f in folders.items() if d < depth}
            if name.endswith('/'):
                folders[depth] = name
            else:
                named[package].add(''.join(folders[d] for d in sorted(folders)) + name)
    return named


def tree():
    """Return each ``ibvs_*`` package under ros2_ws/src with its modules' paths."""
    return {pkg.name: {f.relative_to(pkg / pkg.name).as_posix()
                       for f in (pkg / pkg.name).rglob('*.py') if f.name != '__init__.py'}
            for pkg in sorted(SRC.glob('ibvs_*')) if (pkg / 'package.xml').is_file()}


def test_the_design_map_names_every_package():
    named, packages = design_map(DESIGN.read_text(encoding='utf-8')), tree()
    assert sorted(set(packages) - set(named)) == [], 'packages missing from design.md §2'
    assert sorted(set(named) - set(packages)) == [], 'design.md §2 names packages not in the tree'


def test_the_design_map_names_every_module():
    named, packages = design_map(DESIGN.read_text(encoding='utf-8')), tree()
    missing = [f'{pkg}/{m}' for pkg in packages
               for m in sorted(packages[pkg] - named.get(pkg, set()))]
    stale = [f'{pkg}/{m}' for pkg in named if pkg in packages
             for m in sorted(named[pkg] - packages[pkg])]
    assert missing == [], f'modules design.md §2 does not name: {missing}'
    assert stale == [], f'design.md §2 names modules that do not exist: {stale}'


def test_the_map_reader_takes_folders_and_skips_what_is_no_package():
    text = ('# Design\n\n## 2. Layout\n\n```\nros2_ws/src/\n'
            '  ibvs_a/     what a is\n'
            '    one.py    the first module, whose line\n'
            '              goes on (two.py here is prose)\n'
            '    sub/      a subpackage:\n'
            '      deep.py in it\n'
            '    three.py  back in ibvs_a\n'
            '  tf2_msgs/   no ibvs package\n'
            '    four.py   not counted\n'
            '  ibvs_c/     after it\n'
            '    five.py   counted\n'
            'tests/        the tests\n'
            '    six.py    not of ibvs_c\n'
            '```\n\n```\n  ibvs_b/\n```\n\n## 3. Next\n')
    assert design_map(text) == {'ibvs_a': {'one.py', 'sub/deep.py', 'three.py'},
                                'ibvs_c': {'five.py'}}
