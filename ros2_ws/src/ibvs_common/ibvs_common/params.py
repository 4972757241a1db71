"""
Parameters declared with descriptors (units, ranges) and validated when a node starts.

A :class:`Param` and its :meth:`Param.check` are plain Python (only :meth:`Param.descriptor`
needs ROS), so a pure module can hold the one definition of its tuning and check it.
A pure core takes its configuration as a frozen dataclass (:class:`ParamConfig`) whose
fields are Params (:func:`param_field`): name, default and allowed values are declared once,
in the Param; a node builds it from its declared values (:meth:`ParamConfig.from_values`),
a test directly.

A bad value raises :class:`ParameterError` with a message that names the parameter and
the allowed range; :func:`ibvs_common.node_main.run` turns it into a fatal log line and a
non-zero exit code. A name that nobody declares is refused by :func:`check_declared`, with
the closest declared names: by ``ibvs run`` for the graph
(:func:`ibvs_bringup.graph_params.check`) and by each node's executable for its process
(:func:`ibvs_common.node_main.check_arguments`), in the same words.
"""

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
import difflib
import math
import re
from typing import Any, Self, TYPE_CHECKING

if TYPE_CHECKING:
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.node import Node


class ParameterError(ValueError):
    """
    A parameter has a value outside its allowed range or of the wrong kind.

    ``param``: the name of the parameter at fault, where one is (None otherwise).
    """

    def __init__(self, message: str, param: str | None = None) -> None:
        """Keep the message and the parameter's name."""
        super().__init__(message)
        self.param = param


@dataclass(frozen=True)
class Param:
    """
    One parameter: name, default, meaning, units and what values are allowed.

    ``low``/``high`` bound a number or every element of an array (inclusive unless
    ``low_open``/``high_open``); ``choices`` lists the allowed strings or numbers;
    ``length`` fixes an array's length.
    """

    name: str
    default: object
    description: str
    units: str = ''
    low: float = None
    high: float = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple = None
    length: int = None
    read_only: bool = True

    def allowed(self) -> str:
        """Describe the allowed values in words, for descriptors and error messages."""
        if self.choices is not None:
            return 'one of ' + ', '.join(repr(c) for c in self.choices)
        if isinstance(self.default, bool):
            return 'true or false'
        if self._strings():
            return f'{self.length or "any number of"} strings'
        if isinstance(self.default, str):
            return 'any string'
        lo = '-inf' if self.low is None else f'{self.low:g}'
        hi = 'inf' if self.high is None else f'{self.high:g}'
        text = f"{'(' if self.low_open or self.low is None else '['}{lo}, {hi}" \
               f"{')' if self.high_open or self.high is None else ']'}"
        if self.length is not None:
            text = f'{self.length} values, each in {text}'
        return text

    def _strings(self):
        """Return whether the parameter is an array of strings (its default is one)."""
        return isinstance(self.default, (list, tuple)) and bool(self.default) and \
            isinstance(self.default[0], str)

    def kind(self) -> str:
        """Return the ROS type a value must have, in words (``a double``, ``an array of...``)."""
        if isinstance(self.default, (list, tuple)):
            element = 'string' if self._strings() else 'integer' if self._integer() \
                else 'double'
            count = '' if self.length is None else f'{self.length} '
            return f'an array of {count}{element}s'
        if isinstance(self.default, bool):
            return 'a boolean'
        if isinstance(self.default, str):
            return 'a string'
        return 'an integer' if self._integer() else 'a double'

    def _integer(self):
        """Return whether the parameter is an integer or an array of integers."""
        if isinstance(self.default, (list, tuple)):
            return bool(self.default) and isinstance(self.default[0], int) and \
                not isinstance(self.default[0], bool)
        return isinstance(self.default, int) and not isinstance(self.default, bool)

    def descriptor(self) -> 'ParameterDescriptor':
        """Return the ParameterDescriptor shown by ``ros2 param describe``."""
        # Imported here: a Param (and its check) is pure Python, usable without ROS.
        from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
        desc = ParameterDescriptor(
            description=f'{self.description} [{self.units or "-"}]; allowed: {self.allowed()}',
            read_only=self.read_only)
        if self.length is None and self.choices is None and not isinstance(self.default, bool):
            if isinstance(self.default, int) and self.low is not None and self.high is not None:
                desc.integer_range = [IntegerRange(from_value=int(self.low),
                                                   to_value=int(self.high), step=0)]
            elif isinstance(self.default, float) and self.low is not None \
                    and self.high is not None:
                desc.floating_point_range = [FloatingPointRange(
                    from_value=float(self.low), to_value=float(self.high), step=0.0)]
        return desc

    def check(self, value: Any) -> Any:
        """Return ``value`` if allowed, else raise :class:`ParameterError` naming the parameter."""
        def fail(why):
            raise ParameterError(
                f"parameter '{self.name}' = {value!r} is invalid: {why};"
                f' allowed: {self.allowed()}', self.name)

        def wrong_type(why):
            must = '' if why == f'not {self.kind()}' else f': it must be {self.kind()}'
            fail(f'{why}{must}{number_hint(value)}')

        if self.choices is not None:
            if value not in self.choices:
                fail('not an allowed choice')
            return value
        if isinstance(self.default, str):
            if not isinstance(value, str):
                wrong_type('not a string')
            return value
        if isinstance(self.default, bool):
            if not isinstance(value, bool):
                wrong_type('not a boolean')
            return value
        array = isinstance(self.default, (list, tuple))
        if array != isinstance(value, (list, tuple)):
            wrong_type('an array' if not array else
                       'not an array of strings' if self._strings() else 'not an array')
        if self._strings():
            if not all(isinstance(v, str) for v in value):
                wrong_type('not an array of strings')
            if self.length is not None and len(value) != self.length:
                fail(f'has {len(value)} values')
            return list(value)
        values = list(value) if array else [value]
        if self.length is not None and len(values) != self.length:
            fail(f'has {len(values)} values')
        integer = self._integer()
        for v in values:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                wrong_type('not a number')
            if integer and not isinstance(v, int):
                wrong_type('not an integer')
            if not math.isfinite(v):
                fail('not finite')
            if self.low is not None and (v < self.low or (self.low_open and v == self.low)):
                fail('out of range')
            if self.high is not None and (v > self.high or (self.high_open and v == self.high)):
                fail('out of range')
        return value


def number_hint(value: Any) -> str:
    """
    Say why a text that reads as a number is a string here, or '' if it does not.

    rcl types a value by C's ``strtoll``/``strtod`` (:func:`ibvs_common.ros_args.scalar`),
    so a ``-p`` or a node's parameter file reads ``1e-300`` as a double; a YAML 1.1 reader
    (PyYAML: a study spec, a value written through ``yaml.safe_load``) reads a number with
    an exponent but no dot as a string. Out of a double's normal range (``1e400``,
    ``1e-310``), with ``_`` or ``:`` or in quotes, a number stays a string to rcl too.
    """
    from .ros_args import scalar
    texts = value if isinstance(value, (list, tuple)) else [value]
    for text in texts:
        if not isinstance(text, str):
            continue
        try:
            float(text.replace(':', '').strip())
        except ValueError:
            continue
        plain = re.fullmatch(r'\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*', text)
        if isinstance(scalar(text), (int, float)) and not isinstance(scalar(text), bool):
            why = 'YAML 1.1 reads a number with an exponent as a number only with a dot'
        elif '_' in text or ':' in text:
            why = "rcl reads no '_' or ':' in a number"
        elif plain:
            why = "it is out of a double's normal range, about 2.2e-308 to 1.8e308"
        else:
            why = 'a quoted number is a string'
        return (f'; {text!r} is read as a string ({why}): write a number with a dot, '
                'unquoted, e.g. 1.0e-300')
    return ''


#: Parameters that rclpy declares on every node itself, never refused as undeclared
#: (``qos_overrides.*`` too, the QoS overrides a node may accept).
ROS_PARAMS = ('use_sim_time', 'start_type_description_service')


#: Parameters that no node declares any more, by name, with what took their place. A
#: parameter file or override that still sets one is refused with these words
#: (:func:`check_retired`), by ``ibvs run`` and by a node at start, not ignored as an
#: undeclared override is by rclpy: it would no longer do what it says.
RETIRED = {
    'lockstep': "the time mode follows from command_interface ('effort': lockstep, "
                "'position': free-running)",
    'renderer': 'the simulator renders with OpenGL (ibvs_sim.gl_renderer)',
}


def check_retired(names: Iterable[str], where: str = 'parameter') -> None:
    """
    Raise :class:`ParameterError` for the first of ``names`` that is :data:`RETIRED`.

    The message names it and what replaces it (``where``, unless the default, starts it:
    e.g. ``-p`` or a parameter file).
    """
    for name in names:
        if name in RETIRED:
            lead = '' if where == 'parameter' else f'{where}: '
            raise ParameterError(f"{lead}parameter '{name}' is retired: {RETIRED[name]}", name)


def check_declared(names: Iterable[str], known: Iterable[str], where: str = 'parameter',
                   owner: str = 'no node of the graph') -> None:
    """
    Raise :class:`ParameterError` for the first of ``names`` that is not in ``known``.

    The message names it, says that ``owner`` does not declare it, and offers the closest
    names of ``known`` (``where`` starts it: e.g. ``-p`` or a scenario file); a
    :data:`RETIRED` name is refused with what replaces it (:func:`check_retired`). rclpy
    keeps an override that no declaration takes and says nothing: a misspelt name would
    leave the parameter at its default. :data:`ROS_PARAMS` and ``qos_overrides.*`` always
    pass.
    """
    known = list(known)
    for name in names:
        check_retired([name], where)
        if name in known or name in ROS_PARAMS or str(name).startswith('qos_overrides.'):
            continue
        near = difflib.get_close_matches(str(name), known, n=3)
        raise ParameterError(
            f"{where} '{name}': {owner} declares it"
            + (f"; did you mean {', '.join(repr(n) for n in near)}?" if near else
               '; `ros2 param list` on a running graph lists the declared names'), name)


def plain_value(value: Any, default: Any) -> Any:
    """Convert rclpy's value to plain Python, integers to floats where the default is a float."""
    if hasattr(value, 'tolist'):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        value = list(value)
        if isinstance(default, (list, tuple)) and default and isinstance(default[0], float):
            value = [float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                     for v in value]
        return value
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


#: A rule between parameters: called with the values by name, raises ParameterError naming
#: the parameters when they do not go together (its result, if any, is the node's to use).
Rule = Callable[[Mapping[str, Any]], Any]


def check_rules(rules: Iterable[Rule], values: Mapping[str, Any]) -> None:
    """
    Run each rule on ``values``: ParameterError from the first one broken.

    A node module lists its rules as ``RULES``; the node runs them at start (:func:`declare`)
    and ``ibvs run`` before any node starts (:func:`ibvs_bringup.graph_params.check_rules`),
    so that each rule is one function, called by both.
    """
    for rule in rules:
        rule(values)


def declare(node: 'Node', specs: Iterable[Param], rules: Iterable[Rule] = ()
            ) -> dict[str, Any]:
    """
    Declare every :class:`Param` on ``node`` and return their validated values by name.

    Integer defaults accept integer values only; float defaults also accept integers
    (a YAML ``1`` for a float parameter is a common slip), which are converted. ``rules``:
    the node's rules between parameters (its module's ``RULES``), run on the values
    (:func:`check_rules`). An override of a :data:`RETIRED` parameter is refused
    (:func:`check_retired`).
    """
    # rclpy keeps the overrides (-p, parameter files, parameter_overrides) of the node and
    # has no public reader of those that no declaration takes.
    check_retired(getattr(node, '_parameter_overrides', None) or ())
    values = {}
    for spec in specs:
        descriptor = spec.descriptor()
        # Types are checked by Param.check, which names the allowed range; rclpy's own
        # static typing would reject a YAML 1 for a float with a less helpful message.
        descriptor.dynamic_typing = True
        try:
            param = node.declare_parameter(spec.name, spec.default, descriptor)
        except Exception as exc:  # rclpy raises several types for a bad override
            raise ParameterError(f"parameter '{spec.name}': {exc}; allowed: {spec.allowed()}") \
                from None
        values[spec.name] = spec.check(plain_value(param.value, spec.default))
    check_rules(rules, values)
    return values


def param_field(spec: Param) -> Any:
    """
    Return a dataclass field named after ``spec`` that carries it and takes its default.

    For the fields of a :class:`ParamConfig`; an array default becomes a tuple.
    """
    default = tuple(spec.default) if isinstance(spec.default, list) else spec.default
    return field(default=default, metadata={'param': spec})


def group_field(group: type['ParamConfig']) -> Any:
    """
    Return a dataclass field holding the nested :class:`ParamConfig` ``group``, at its defaults.

    A group is a set of parameters several nodes read together, with the rules between them
    and what follows from them, in one place (:mod:`ibvs_common.shared_params`: the timing,
    the target, the plant). Its parameters keep their own ROS names: a node declares them
    flat, as it declares its own, and :meth:`ParamConfig.params`, :meth:`ParamConfig.values`
    and :meth:`ParamConfig.from_values` see through the group.
    """
    return field(default_factory=group, metadata={'group': group})


class ParamConfig:
    """
    Base of a frozen dataclass whose fields are Params (:func:`param_field`) or groups.

    Construction checks each such field with its :meth:`Param.check` (ParameterError
    naming it; an integer for a float parameter becomes a float, an array a tuple), so a
    core that takes the config checks no single value again. A group field
    (:func:`group_field`) holds a nested ParamConfig, checked by its own construction.
    Fields without a Param are left as given. :meth:`make` builds one from parameter values
    by name, wherever they sit.
    """

    #: Rules between parameters (:func:`check_rules`), run on the values at a node's start
    #: and by ``ibvs run`` before any node starts; a group's cross-checks are its own
    #: construction's.
    RULES = ()

    def __post_init__(self):
        """Check every Param field and store it in plain Python (arrays as tuples)."""
        for f in fields(self):
            group = f.metadata.get('group')
            if group is not None and not isinstance(getattr(self, f.name), group):
                raise TypeError(f'{type(self).__name__}.{f.name} must be a {group.__name__}, '
                                f'not {getattr(self, f.name)!r}')
            spec = f.metadata.get('param')
            if spec is None:
                continue
            if spec.name != f.name:
                raise TypeError(f'{type(self).__name__}.{f.name} carries the parameter '
                                f"'{spec.name}': a field must be named after its parameter")
            value = spec.check(plain_value(getattr(self, f.name), spec.default))
            object.__setattr__(self, f.name, tuple(value) if isinstance(value, list) else value)

    @classmethod
    def params(cls) -> tuple[Param, ...]:
        """Return the :class:`Param` of each field, a group's in its place, in field order."""
        out = []
        for f in fields(cls):
            if 'group' in f.metadata:
                out.extend(f.metadata['group'].params())
            elif 'param' in f.metadata:
                out.append(f.metadata['param'])
        return tuple(out)

    def values(self) -> dict[str, Any]:
        """Return the Param values by name, the groups' too: what the shared rules take."""
        out = {}
        for f in fields(self):
            if 'group' in f.metadata:
                out.update(getattr(self, f.name).values())
            elif 'param' in f.metadata:
                out[f.name] = getattr(self, f.name)
        return out

    def off_default(self, names: tuple[str, ...]) -> list[tuple[str, Any]]:
        """Return (name, value) of each of ``names`` whose value is not its default."""
        values, defaults = self.values(), type(self)().values()
        return [(name, values[name]) for name in names if values[name] != defaults[name]]

    @classmethod
    def from_values(cls, values: Mapping[str, Any], **others: Any) -> Self:
        """
        Return the config of the parameter values ``values`` (a mapping by name).

        Every Param field, a group's too, is taken from ``values`` (KeyError if one is
        missing: a node declares them all, e.g. with ``declare(node, Config.params() +
        ...)``); ``others`` sets the fields without a Param.
        """
        kwargs = {}
        for f in fields(cls):
            if 'group' in f.metadata:
                kwargs[f.name] = f.metadata['group'].from_values(values)
            elif 'param' in f.metadata:
                kwargs[f.name] = values[f.name]
        return cls(**kwargs, **others)

    @classmethod
    def make(cls, **values: Any) -> Self:
        """
        Return the config of these parameter values by name, every other at its default.

        A group's parameters are given by their own names (``make(camera_rate_hz=60.0)``,
        not through the group); a name that is neither a parameter of ``cls`` nor one of its
        fields without a Param raises TypeError.
        """
        names = {spec.name for spec in cls.params()}
        others = {f.name for f in fields(cls) if not f.metadata}
        unknown = sorted(set(values) - names - others)
        if unknown:
            raise TypeError(f'{cls.__name__} has no parameter {", ".join(unknown)}')
        defaults = {spec.name: spec.default for spec in cls.params()}
        return cls.from_values({**defaults, **{k: v for k, v in values.items() if k in names}},
                               **{k: v for k, v in values.items() if k in others})
