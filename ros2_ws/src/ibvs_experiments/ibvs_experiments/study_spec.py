"""
Study specifications: read and check a study's YAML, expand it into runs, key each run.

Pure Python and numpy (no rclpy, no Ray): what a study *is* lives here; how its runs are
executed lives in :mod:`ibvs_experiments.study`.

A spec (``ibvs study SPEC.yaml``)::

    name: fig13_link_lengths      # optional; default: the file's stem
    description: ...              # optional, free text
    scenario: scenario1           # a scenario name or parameter file (``ibvs run`` takes)
    duration_s: 3.0               # optional sim time per run; default: the scenario's
    run_figures: false            # optional: each run's figures too (default: table, study
                                  # figures and each run's metrics and bag only; ``ibvs
                                  # analyse RUN/bag`` draws a run's figures later)
    parameters: {actuators: ideal}  # optional overrides common to every run
    grid:                         # optional: a product over value lists...
      l2_scale: [0.5, 1.0]
    # ...or a list of products, run one after the other (their union):
    # grid: [{l2_scale: [0.5, 1.0]}, {l4_scale: [0.5, 1.0]}]
    draws:                        # optional: n seeded random draws
      n: 20
      seed: 1
      mode: crossed               # optional: crossed (default) or per_run (below)
      task: {seed: 7}             # optional: a task of the workspace sampler per draw
      parameters:                 # optional when a task is drawn
        feedback_latency_s: {uniform: [0.0, 0.05]}   # low, high
        l2_scale: {normal: [1.0, 0.05]}              # mean, standard deviation
        camera_seed: {integers: [0, 1000]}           # low, high, both included
        camera_pose_error_xyz_m: {uniform: [[-0.01, -0.01, 0.0], [0.01, 0.01, 0.02]]}
                                  # a vector: [lows], [highs] (normal: [means], [stds]),
                                  # one value per element

``mode: crossed``: the runs are every grid point combined with every draw (one run if
neither is given): each grid point sees the same n draws (a paired comparison).
``mode: per_run``: each run gets a draw of its own, n per grid point (n x points draws,
none shared). Draws come from ``numpy.random.default_rng(seed)``, one parameter after the
other in name order (all of a parameter's draws at once), so a spec names the same runs on
any machine.

``task: {seed: S}`` (optionally ``version:``, which must be
:data:`ibvs_model.task_sampler.VERSION`): draw k takes task k of
:func:`ibvs_model.task_sampler.tasks` (the workspace benchmark's tasks: n tasks of seed
S), which sets ``start_joints``, ``target_position`` and ``target_rotation``; the table
names the task (``task``) and its tool-axis observability (``task_observability``). In
``per_run`` mode the study draws n x points tasks.

A value reaches its run as drawn: integers as integers, vectors as lists of floats, and
floats written so that YAML 1.1 reads them back as floats (:func:`yaml_value`; ``1e-05``
is a string to YAML 1.1).
"""

from collections.abc import Mapping
from dataclasses import dataclass
import hashlib
import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np
import yaml

KEYS = ('name', 'description', 'scenario', 'duration_s', 'parameters', 'grid', 'draws',
        'run_figures')
DRAW_KEYS = ('n', 'seed', 'parameters', 'mode', 'task')
REQUIRED_DRAW_KEYS = ('n', 'seed')
#: ``draws.mode``: the same draws at every grid point, or a draw of its own for each run.
DRAW_MODES = ('crossed', 'per_run')
TASK_KEYS = ('seed', 'version')
#: Distribution name -> (what its two numbers are, check of the two numbers). A vector
#: draw gives two lists of the same length instead, checked element by element.
DISTRIBUTIONS = {
    'uniform': ('[low, high] with low < high', lambda a, b: a < b),
    'normal': ('[mean, standard deviation] with standard deviation > 0', lambda a, b: b > 0),
    'integers': ('[low, high], integers with low <= high (both included)',
                 lambda a, b: a <= b),
}


class StudyError(ValueError):
    """A study spec is malformed; the message names the key and what is allowed."""


@dataclass(frozen=True)
class Run:
    """One run of a study: its position, its overrides, and which of them the study varies."""

    index: int
    overrides: dict
    #: The grid and draw values of this run (a subset of ``overrides``, and a drawn task's
    #: ``task`` and ``task_observability``), for tables and plots.
    swept: dict


@dataclass(frozen=True)
class Spec:
    """A checked study spec (module docstring)."""

    name: str
    scenario: str
    duration_s: float = None
    parameters: dict = None
    grid: tuple = ()
    draws: dict = None
    description: str = ''
    #: Whether each run draws its figures (a few seconds each); not part of a run's key.
    run_figures: bool = False

    def swept_names(self) -> list[str]:
        """Return the names of the grid and draw columns, grid first, in spec order."""
        names = [k for product in self.grid for k in product]
        if (self.draws or {}).get('task') is not None:
            names += list(TASK_COLUMNS)
        names += list((self.draws or {}).get('parameters', {}))
        return list(dict.fromkeys(names))

    def origin(self, name: str) -> str:
        """Return where in the spec the value of parameter ``name`` comes from (a path)."""
        for i, product in enumerate(self.grid):
            if name in product:
                return f'grid[{i}].{name}' if len(self.grid) > 1 else f'grid.{name}'
        draws = self.draws or {}
        if name in draws.get('parameters', {}):
            return f'draws.parameters.{name}'
        if draws.get('task') is not None and name in TASK_PARAMETERS:
            return f'draws.task ({name})'
        return f'parameters.{name}'

    def runs(self) -> list['Run']:
        """Return the study's runs: every grid point with every draw (``draws.mode``)."""
        points = [dict(zip(product, values)) for product in self.grid
                  for values in itertools.product(*product.values())] or [{}]
        per_run = (self.draws or {}).get('mode') == 'per_run'
        draws = self._draw_values(len(points) if per_run else 1)
        n = len(draws) // (len(points) if per_run else 1)
        runs = []
        for p, point in enumerate(points):
            for i in range(n):
                draw = draws[p * n + i] if per_run else draws[i]
                swept = {**point, **draw['swept']}
                runs.append(Run(len(runs), {**(self.parameters or {}), **point,
                                            **draw['overrides']}, swept))
        return runs

    def _draw_values(self, sets: int = 1):
        """Return ``sets`` x n draws, each {'swept': ..., 'overrides': ...}."""
        if not self.draws:
            return [{'swept': {}, 'overrides': {}}]
        rng = np.random.default_rng(self.draws['seed'])
        count = self.draws['n'] * sets
        columns = {}
        for name in sorted(self.draws['parameters']):
            (kind, (a, b)), = self.draws['parameters'][name].items()
            columns[name] = _draw(rng, kind, a, b, count)
        out = [{'swept': {name: columns[name][i] for name in self.draws['parameters']},
                'overrides': {name: columns[name][i] for name in self.draws['parameters']}}
               for i in range(count)]
        task = self.draws.get('task')
        if task is not None:
            from ibvs_model import task_sampler
            for draw, t in zip(out, task_sampler.tasks(count, task['seed'])):
                draw['overrides'].update({k: t[k] for k in TASK_PARAMETERS})
                draw['swept'] = {'task': t['id'], 'task_observability': t['observability'],
                                 **draw['swept'], **{k: t[k] for k in TASK_PARAMETERS}}
        return out


#: Parameters a drawn task sets (:func:`ibvs_model.task_sampler.tasks`).
TASK_PARAMETERS = ('start_joints', 'target_position', 'target_rotation')
#: Columns a drawn task adds to the table (besides its parameters).
TASK_COLUMNS = ('task', 'task_observability') + TASK_PARAMETERS


def _draw(rng, kind, a, b, count):
    """Return ``count`` values of distribution ``kind`` with arguments ``a``, ``b``."""
    vector = isinstance(a, tuple)
    size = (count, len(a)) if vector else count
    if kind == 'integers':
        values = rng.integers(a, np.asarray(b) + 1, size)
        return [[int(x) for x in v] if vector else int(v) for v in values]
    values = rng.uniform(a, b, size) if kind == 'uniform' else rng.normal(a, b, size)
    return [[float(x) for x in v] if vector else float(v) for v in values]


def yaml_value(value: Any) -> str:
    """
    Return ``value`` as a YAML flow text that YAML 1.1 (PyYAML, ``-p name:=value``) reads back.

    ``json.dumps(-1e-05)`` is ``-1e-05``, which YAML 1.1 reads as a string (its floats need
    a '.'); PyYAML writes ``-1.0e-05``. Integers stay integers, lists lists.
    """
    text = yaml.safe_dump(value, default_flow_style=True, width=2 ** 31)
    return text[:-len('\n...\n')] if text.endswith('\n...\n') else text.rstrip('\n')


def _number(value, where, integer=False):
    if integer:
        if isinstance(value, bool) or not isinstance(value, int):
            raise StudyError(f'{where}: expected an integer, got {value!r}')
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not np.isfinite(value):
        raise StudyError(f'{where}: expected a finite number, got {value!r}')
    return float(value)


def _mapping(value, where):
    if not isinstance(value, dict):
        raise StudyError(f'{where}: expected a mapping, got {type(value).__name__}')
    for key in value:
        if not isinstance(key, str):
            raise StudyError(f'{where}: parameter names are strings, got {key!r}')
    return value


def _unknown(data, allowed, where):
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise StudyError(f'{where}: unknown key(s) {unknown}; allowed: {list(allowed)}')


def _grid(value):
    products = value if isinstance(value, list) else [value]
    if not products:
        raise StudyError('grid: an empty list; give a mapping of parameter -> values')
    out = []
    for i, product in enumerate(products):
        where = 'grid' if not isinstance(value, list) else f'grid[{i}]'
        product = _mapping(product, where)
        if not product:
            raise StudyError(f'{where}: no parameter')
        for name, values in product.items():
            if not isinstance(values, list) or not values:
                raise StudyError(f'{where}.{name}: expected a non-empty list of values, '
                                 f'got {values!r}')
        out.append(dict(product))
    return tuple(out)


def _args(args, kind, meaning, ok, where):
    """Check a distribution's two arguments: two numbers, or two lists of one length."""
    where = f'{where}.{kind}'
    if not isinstance(args, list) or len(args) != 2:
        raise StudyError(f'{where}: expected {meaning} (or two lists of that, one value per '
                         f'element of a vector), got {args!r}')
    integer = kind == 'integers'
    if all(isinstance(x, list) for x in args):
        if not args[0] or len(args[0]) != len(args[1]):
            raise StudyError(f'{where}: a vector draw needs two non-empty lists of the same '
                             f'length, got {args!r}')
        pairs = [(_number(x, f'{where}[0][{i}]', integer),
                  _number(y, f'{where}[1][{i}]', integer))
                 for i, (x, y) in enumerate(zip(*args))]
        for i, (a, b) in enumerate(pairs):
            if not ok(a, b):
                raise StudyError(f'{where}: element {i}: expected {meaning}, got '
                                 f'[{args[0][i]!r}, {args[1][i]!r}]')
        return tuple(a for a, _ in pairs), tuple(b for _, b in pairs)
    a, b = (_number(x, f'{where}[{i}]', integer) for i, x in enumerate(args))
    if not ok(a, b):
        raise StudyError(f'{where}: expected {meaning}, got {args!r}')
    return a, b


def _task(value):
    value = _mapping(value, 'draws.task')
    _unknown(value, TASK_KEYS, 'draws.task')
    seed = value.get('seed')
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise StudyError(f'draws.task.seed: expected an integer >= 0, got {seed!r}')
    from ibvs_model import task_sampler
    version = value.get('version', task_sampler.VERSION)
    if version != task_sampler.VERSION:
        raise StudyError(f'draws.task.version: {version!r} is not the sampler installed '
                         f'({task_sampler.VERSION!r}): its tasks cannot be drawn again')
    return {'seed': seed, 'version': version}


def _draws(value):
    value = _mapping(value, 'draws')
    _unknown(value, DRAW_KEYS, 'draws')
    for key in REQUIRED_DRAW_KEYS:
        if key not in value:
            raise StudyError(f'draws: missing {key!r} (draws need n, seed, and parameters '
                             'and/or task)')
    n, seed = value['n'], value['seed']
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise StudyError(f'draws.n: expected an integer >= 1, got {n!r}')
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise StudyError(f'draws.seed: expected an integer >= 0, got {seed!r}')
    mode = value.get('mode', 'crossed')
    if mode not in DRAW_MODES:
        raise StudyError(f'draws.mode: expected one of {list(DRAW_MODES)}, got {mode!r}')
    task = _task(value['task']) if 'task' in value else None
    params = _mapping(value.get('parameters') or {}, 'draws.parameters')
    if not params and task is None:
        raise StudyError('draws.parameters: no parameter to draw (and no draws.task)')
    checked = {}
    for name, dist in params.items():
        where = f'draws.parameters.{name}'
        if not isinstance(dist, dict) or len(dist) != 1:
            raise StudyError(f'{where}: expected one distribution, one of '
                             f'{list(DISTRIBUTIONS)}, e.g. {{uniform: [0.0, 1.0]}}; '
                             f'got {dist!r}')
        (kind, args), = dist.items()
        if kind not in DISTRIBUTIONS:
            raise StudyError(f'{where}: unknown distribution {kind!r}; known: '
                             f'{list(DISTRIBUTIONS)}')
        checked[name] = {kind: _args(args, kind, *DISTRIBUTIONS[kind], where)}
    if task is not None:
        both = sorted(set(checked) & set(TASK_PARAMETERS))
        if both:
            raise StudyError(f'draws.parameters.{both[0]}: set by draws.task; draw it or '
                             'draw the task, not both')
    return {'n': n, 'seed': seed, 'mode': mode, 'task': task, 'parameters': checked}


def parse(data: Any, default_name: str = 'study') -> Spec:
    """Check a spec's data (parsed YAML) and return a :class:`Spec`; raise StudyError."""
    data = _mapping(data, 'study spec')
    _unknown(data, KEYS, 'study spec')
    if not isinstance(data.get('scenario'), str) or not data['scenario']:
        raise StudyError("study spec: 'scenario' (a scenario name or parameter file) is "
                         'required')
    name = data.get('name', default_name)
    if not isinstance(name, str) or not name or '/' in name:
        raise StudyError(f'name: expected a non-empty string without "/", got {name!r}')
    duration = data.get('duration_s')
    if duration is not None and _number(duration, 'duration_s') <= 0:
        raise StudyError(f'duration_s: expected a number > 0, got {duration!r}')
    params = dict(_mapping(data.get('parameters') or {}, 'parameters'))
    run_figures = data.get('run_figures', False)
    if not isinstance(run_figures, bool):
        raise StudyError(f'run_figures: expected true or false, got {run_figures!r}')
    grid = _grid(data['grid']) if 'grid' in data else ()
    draws = _draws(data['draws']) if 'draws' in data else None
    in_grid = [k for product in grid for k in product]
    drawn = set((draws or {}).get('parameters', {}))
    if (draws or {}).get('task') is not None:
        drawn |= set(TASK_PARAMETERS)
    overlap = sorted(set(in_grid) & drawn)
    if overlap:
        raise StudyError(f'{overlap}: a parameter is either on the grid or drawn, not both')
    clash = sorted(set(params) & (set(in_grid) | drawn))
    if clash:
        raise StudyError(f'{clash}: a parameter is fixed (parameters) or varied (grid, draws), '
                         'not both')
    return Spec(name=name, scenario=data['scenario'],
                duration_s=None if duration is None else float(duration),
                parameters=params, grid=grid, draws=draws,
                description=str(data.get('description', '')), run_figures=run_figures)


def load(path: str | Path) -> Spec:
    """Read and check the spec file at ``path``."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise StudyError(f'{path}: not valid YAML: {exc}') from None
    try:
        return parse(data, default_name=path.stem)
    except StudyError as exc:
        raise StudyError(f'{path}: {exc}') from None


def run_key(scenario_params: Mapping[str, Any], overrides: Mapping[str, Any],
            duration_s: float, code_version: str) -> str:
    """
    Return the cache key of a run: SHA-256 of everything that decides its result.

    ``scenario_params`` are the base scenario's parameters as read from its file, so that
    an edited scenario file is a new run; ``code_version`` names the code (see
    :func:`ibvs_experiments.study.code_version`).
    """
    blob = json.dumps({'scenario': scenario_params, 'overrides': overrides,
                       'duration_s': duration_s, 'code': code_version},
                      sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()
