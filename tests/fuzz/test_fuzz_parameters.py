"""
Wrong-typed parameters into every node of the graph, however they come: refused, named.

A node is started as docs/running.md starts it, ``--ros-args --params-file
scenario1.yaml``; rcl's merge drops a ``-p`` of the wrong type after a file that sets the
parameter without a word (``-p camera_rate_hz:=abc``: rclpy alone would run the node with
the file's 30.0). For every parameter each node declares (its module's
``PARAMS``) three cases, checked as the node's ``main`` checks its command line before
rclpy starts (:func:`ibvs_common.node_main.check_arguments`; exit code 2 in the process,
tests/test_ros_args.py): ``-p`` of the wrong type after the scenario file; a parameter file
that gives the right value, then ``-p`` the wrong one; a parameter file that gives the
wrong one. Each must raise ParameterError naming the parameter: another exception is a
crash, none an accept in silence. The table gets a row per node.
"""

import importlib

from ibvs_bringup import scenario
from ibvs_bringup.graph import GRAPH
from ibvs_common.node_main import check_arguments
from ibvs_common.params import ParameterError
import pytest

from .harness import TABLES

#: A value of another type than the parameter's, as rcl reads it (and as a file writes it):
#: an integer for a string, a string for anything else.
WRONG = {str: 7}
WRONG_DEFAULT = 'abc'


def _declared(node):
    """Return the node's class and the parameters it declares whose type a file can give."""
    module = importlib.import_module(node.module)
    # An empty array's type is none to rcl; None is no value.
    return getattr(module, node.cls), [p for p in module.PARAMS
                                       if p.default is not None and p.default != []]


def _cases(param, tmp_path):
    """Return (name, argv) of the three ways ``param`` comes with a value of the wrong type."""
    wrong = WRONG.get(type(param.default), WRONG_DEFAULT)
    base = ['node', '--ros-args', '--params-file', str(scenario.scenario_path('scenario1'))]
    right = scenario.write_parameters({param.name: param.default},
                                      tmp_path / f'{param.name}_right.yaml')
    bad = scenario.write_parameters({param.name: wrong}, tmp_path / f'{param.name}_wrong.yaml')
    rule = ['-p', f'{param.name}:={wrong}']
    return [('-p after the scenario file', base + rule),
            ('a file of the right value, then -p', base + ['--params-file', str(right)] + rule),
            ('a file of the wrong value', base + ['--params-file', str(bad)])]


@pytest.mark.parametrize('node', GRAPH.nodes, ids=lambda n: n.name)
def test_fuzz_parameters_of_the_wrong_type(node, tmp_path):
    cls, params = _declared(node)
    crashes, silent, count = [], [], 0
    for param in params:
        for name, argv in _cases(param, tmp_path):
            count += 1
            try:
                check_arguments([cls], argv)
            except ParameterError as exc:
                if exc.param != param.name:
                    silent.append(f'{param.name} {name}: refused naming {exc.param!r}: {exc}')
            except Exception as exc:  # what the node's start would not survive
                crashes.append(f'{param.name} {name}: {type(exc).__name__}: {exc}')
            else:
                silent.append(f'{param.name} {name}: accepted')
    TABLES.append(f'{node.name + " params":32s} {count:5d} {len(crashes):7d} {0:5d} '
                  f'{len(silent):17d} {0:18d}   parameters {len(params)}')
    TABLES.extend(f'    {line}' for line in crashes + silent)
    assert not crashes and not silent, '\n'.join(crashes + silent)
    assert count >= 3, 'no parameter: nothing was tested'
