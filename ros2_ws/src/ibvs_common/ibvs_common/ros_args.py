"""
The parameter values of ``--ros-args`` (``-p`` and ``--params-file``) as rcl reads them.

Pure Python, read before rclpy starts, so that a value of the wrong type is refused however
it arrives. Two things of rcl's are followed exactly, because the values a node gets are
rcl's (measured against rclpy 7, Jazzy):

- The type of a value (rcl_yaml_param_parser's ``get_value``): a quoted or ``!!str`` scalar
  is a string; otherwise one of ``Y y yes Yes YES true True TRUE on On ON`` (and the
  matching false words) is a boolean, a whole C ``strtoll`` number (base 0: ``0x10`` is 16,
  ``010`` is 8) an integer, a whole C ``strtod`` number (``1e-300``, ``1E5``, ``inf``,
  ``.inf``, ``0x1p3``; not one out of a double's range, ``1e400`` or ``1e-310``) a double,
  anything else a string (``1_000``, ``1:2``, ``~``). PyYAML differs on several of these
  (it reads ``1e-300`` as a string and ``1:2`` as 62).
- The merge: ``-p`` and the files' sections land in one table of node sections (a ``-p``
  without ``node:`` in ``/**``), in command-line order; rclpy applies the sections that
  match a node in the order each first appeared, a later one replacing a parameter. Within
  one section a later value replaces an earlier one only if both have the same type: of
  values of different types rclpy keeps the first of boolean, integer, double, string,
  then the arrays, whatever came last (:meth:`Given.kept`). A ``-p camera_rate_hz:=abc``
  after a file's ``camera_rate_hz: 30.0`` is so dropped without a word.
"""

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
import math
from pathlib import Path
import re
import sys

import yaml

TRUE_WORDS = ('Y', 'y', 'yes', 'Yes', 'YES', 'true', 'True', 'TRUE', 'on', 'On', 'ON')
FALSE_WORDS = ('N', 'n', 'no', 'No', 'NO', 'false', 'False', 'FALSE', 'off', 'Off', 'OFF')
#: rcl's special double words, read by name.
_SPECIAL = {'.nan': math.nan, '.NaN': math.nan, '.NAN': math.nan}
_SPECIAL.update({f'{sign}{word}': (-math.inf if sign == '-' else math.inf)
                 for sign in ('', '+', '-') for word in ('.inf', '.Inf', '.INF')})
_INT = re.compile(r'[ \t\n\v\f\r]*([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)\Z')
_DEC = re.compile(r'[ \t\n\v\f\r]*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\Z')
_HEX = re.compile(r'[ \t\n\v\f\r]*([+-]?)0[xX]([0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)'
                  r'([pP][+-]?\d+)?\Z')
_INF_NAN = re.compile(r'[ \t\n\v\f\r]*([+-]?)(inf|infinity|nan(\([0-9A-Za-z_]*\))?)\Z',
                      re.IGNORECASE)
#: rclpy's order of preference among the types of one parameter in one section.
TYPE_ORDER = ('boolean', 'integer', 'double', 'string', 'boolean array', 'integer array',
              'double array', 'string array')
#: The flags of ``--ros-args`` that take a value (rcl's arguments.h), besides -p,
#: --params-file and -r.
VALUED_FLAGS = ('-e', '--enclave', '--log-level', '--log-file-name', '--log-config-file')
#: A value rcl cannot type (a nested array, one of mixed types): left to rcl to refuse.
UNTYPED = object()


class ArgumentsError(ValueError):
    """A parameter file cannot be read or is not a ROS 2 parameter file."""


def _double(text: str) -> float | None:
    """Return ``text`` as C's ``strtod`` reads the whole of it without ERANGE, else None."""
    special = _INF_NAN.match(text)
    if special:
        if special.group(2).lower().startswith('nan'):
            return math.nan
        return -math.inf if special.group(1) == '-' else math.inf
    hexa = _HEX.match(text)
    if hexa:
        value = float.fromhex(text.strip())
    elif _DEC.match(text):
        value = float(text.strip())
    else:
        return None
    if math.isinf(value):
        return None  # overflow: ERANGE
    if value == 0.0:
        mantissa = (hexa.group(2) if hexa else _DEC.match(text).group(1))
        if any(c not in '0.' for c in mantissa):
            return None  # underflow to zero: ERANGE
    elif abs(value) < sys.float_info.min:
        return None  # a subnormal result: glibc's ERANGE
    return value


def scalar(text: str, quoted: bool = False) -> bool | int | float | str:
    """Return the value rcl reads from a YAML scalar ``text`` (``quoted``: a string)."""
    if quoted:
        return text
    if text in TRUE_WORDS:
        return True
    if text in FALSE_WORDS:
        return False
    match = _INT.match(text)
    if match:
        digits = match.group(2)
        value = int(digits, 16) if digits[:2] in ('0x', '0X') else int(digits, 8) \
            if digits.startswith('0') else int(digits)
        value = -value if match.group(1) == '-' else value
        if -2 ** 63 <= value < 2 ** 63:
            return value
    if text in _SPECIAL:
        return _SPECIAL[text]
    value = _double(text)
    return text if value is None else value


def type_name(value: object) -> str:
    """Return the rcl type of ``value`` in words (:data:`TYPE_ORDER`)."""
    if isinstance(value, list):
        return (type_name(value[0]) + ' array') if value else 'array'
    if isinstance(value, bool):
        return 'boolean'
    return {int: 'integer', float: 'double'}.get(type(value), 'string')


class _Loader(yaml.SafeLoader):
    """A YAML loader that marks a plain (unquoted, untagged) scalar for rcl's typing."""

    def resolve(self, kind, value, implicit):
        """Tag a plain scalar ``!plain``; a quoted or tagged one keeps YAML's tag."""
        if kind is yaml.ScalarNode and implicit[0]:
            return '!plain'
        return super().resolve(kind, value, implicit)


def _value(node: yaml.Node, mixed: bool = False) -> object:
    """
    Return rcl's value of a scalar or a sequence of scalars of one type (else UNTYPED).

    ``mixed``: a sequence of scalars of several types is a list too (rcl refuses it).
    """
    if isinstance(node, yaml.ScalarNode):
        return scalar(node.value, quoted=node.tag != '!plain')
    if isinstance(node, yaml.SequenceNode) and \
            all(isinstance(item, yaml.ScalarNode) for item in node.value):
        values = [_value(item) for item in node.value]
        if mixed or len({type_name(v) for v in values}) <= 1:
            return values
    return UNTYPED


def parse_rule(text: str, mixed: bool = False) -> tuple[str, str, object] | None:
    """
    Return (node section, name, value) of a ``-p [node:]name:=value`` rule.

    The section of a rule without ``node:`` is ``/**``. None for a rule rcl refuses (rcl
    says why when rclpy starts). ``mixed``: an array of values of several types (``[0.1,
    0]``, which rcl refuses) is a list of each one's value, for a reader that types it
    itself (``ibvs run``'s ``-p``).
    """
    if ':=' not in text:
        return None
    key, raw = text.split(':=', 1)
    node, _, name = key.rpartition(':')
    try:
        parsed = yaml.compose(raw, Loader=_Loader)
    except yaml.YAMLError:
        return None
    if parsed is None or not name:
        return None
    return (node or '/**'), name, _value(parsed, mixed)


def _parameters(node: yaml.Node, prefix: str = '') -> Iterator[tuple[str, object]]:
    """Yield (dotted name, value) of a ``ros__parameters`` mapping, nested names dotted."""
    for key, value in node.value:
        name = f'{prefix}{key.value}'
        if isinstance(value, yaml.MappingNode):
            yield from _parameters(value, name + '.')
        else:
            yield name, _value(value)


def _sections(node: yaml.Node, path: tuple[str, ...] = ()
              ) -> Iterator[tuple[str, list[tuple[str, object]]]]:
    for key, value in node.value:
        if not isinstance(value, yaml.MappingNode) or not isinstance(key, yaml.ScalarNode):
            raise ArgumentsError("expected 'NODE: ros__parameters: {...}' sections "
                                 '(NODE /** for every node)')
        if key.value == 'ros__parameters':
            yield '/'.join(path), list(_parameters(value))
        else:
            yield from _sections(value, path + (key.value.strip('/'),))


def file_sections(path: str | Path) -> list[tuple[str, list[tuple[str, object]]]]:
    """
    Return the (node section, [(name, value)...]) of a parameter file, in file order.

    Raises :class:`ArgumentsError` (naming the file) for a file that cannot be read, is not
    YAML or is not a ROS 2 parameter file (``node: {ros__parameters: {...}}``).
    """
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ArgumentsError(f'parameter file {path}: cannot read it: {exc.strerror}') \
            from None
    except UnicodeDecodeError as exc:
        raise ArgumentsError(f'parameter file {path}: not valid YAML: {exc}') from None
    try:
        root = yaml.compose(text, Loader=_Loader)
    except yaml.YAMLError as exc:
        raise ArgumentsError(f'parameter file {path}: not valid YAML: {exc}') from None
    try:
        if not isinstance(root, yaml.MappingNode):
            raise ArgumentsError("expected 'NODE: ros__parameters: {...}' sections "
                                 '(NODE /** for every node)')
        sections = list(_sections(root))
    except ArgumentsError as exc:
        raise ArgumentsError(f'parameter file {path}: {exc}') from None
    return [('/' + key.lstrip('/'), params) for key, params in sections]


@dataclass
class Given:
    """The values one section gives a parameter, in command-line order, with their origins."""

    values: list[tuple[object, str]] = field(default_factory=list)

    def last(self) -> tuple[object, str]:
        """Return (value, origin) given last: the one meant."""
        return self.values[-1]

    def kept(self) -> tuple[object, str]:
        """Return (value, origin) that rclpy keeps: the last of the first type of TYPE_ORDER."""
        by_type = {}
        for value, origin in self.values:
            by_type[type_name(value)] = (value, origin)
        for name in TYPE_ORDER:
            if name in by_type:
                return by_type[name]
        return self.last()


@dataclass
class RosArguments:
    """
    The parameters, remappings of the node name and parameter files of a command line.

    ``sections``: {section: {name: :class:`Given`}} in the order each section first
    appeared; ``files``: the ``--params-file`` paths; ``rules``: the ``-p`` rule names;
    ``node_remaps``: (node or '', '__node'/'__ns', new) of ``-r``.
    """

    sections: dict[str, dict[str, Given]] = field(default_factory=dict)
    files: list[str] = field(default_factory=list)
    rule_names: list[str] = field(default_factory=list)
    node_remaps: list[tuple[str, str, str]] = field(default_factory=list)

    def give(self, section: str, name: str, value: object, origin: str) -> None:
        """Add one value to ``section``."""
        section = '/' + section.lstrip('/')
        self.sections.setdefault(section, {}).setdefault(name, Given()).values.append(
            (value, origin))

    def node_name(self, name: str) -> str:
        """Return the fully qualified name of the node ``name`` after the ``-r`` rules."""
        node, namespace = name, '/'
        for target, what, new in self.node_remaps:
            if target and target != name:
                continue
            if what in ('__node', '__name'):
                node = new
            else:
                namespace = '/' + new.strip('/')
        return namespace.rstrip('/') + '/' + node

    def for_node(self, fqn: str) -> dict[str, Given]:
        """Return {name: :class:`Given`} of the sections that match ``fqn``, as rclpy merges."""
        out = {}
        for section, params in self.sections.items():
            if matches(section, fqn):
                out.update(params)
        return out


def matches(section: str, fqn: str) -> bool:
    """Return whether the section ``section`` (``/**``, ``/*``, a name) applies to ``fqn``."""
    pattern = '^' + re.escape(section).replace(r'/\*\*', '(/[^/]+)*').replace(
        r'\*', '[^/]+') + r'\Z'
    return re.match(pattern, fqn) is not None or section == fqn


def parse(argv: Sequence[str]) -> RosArguments:
    """
    Return the :class:`RosArguments` of ``argv``: only what lies in ``--ros-args`` (to ``--``).

    Raises :class:`ArgumentsError` for a parameter file that cannot be read or parsed.
    """
    out = RosArguments()
    inside, i = False, 0
    while i < len(argv):
        arg = argv[i]
        has_value = i + 1 < len(argv)
        if arg == '--ros-args':
            inside = True
        elif arg == '--':
            inside = False
        elif inside and arg in ('-p', '--param') and has_value:
            i += 1
            rule = parse_rule(argv[i])
            out.rule_names.append(argv[i].split(':=', 1)[0].split(':')[-1])
            if rule is not None:
                out.give(rule[0], rule[1], rule[2], f'-p {argv[i]}')
        elif inside and arg == '--params-file' and has_value:
            i += 1
            out.files.append(argv[i])
            for section, params in file_sections(argv[i]):
                for name, value in params:
                    out.give(section, name, value, f'parameter file {argv[i]}')
        elif inside and arg in ('-r', '--remap') and has_value:
            i += 1
            key, _, new = argv[i].partition(':=')
            target, _, what = key.rpartition(':')
            if what in ('__node', '__name', '__ns') and new:
                out.node_remaps.append((target, what, new))
        elif inside and arg in VALUED_FLAGS:
            i += 1
        i += 1
    return out
