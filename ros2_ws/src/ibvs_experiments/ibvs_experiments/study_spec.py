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
      parameters:
        feedback_latency_s: {uniform: [0.0, 0.05]}   # low, high
        l2_scale: {normal: [1.0, 0.05]}              # mean, standard deviation

The runs are every grid point combined with every draw (one run if neither is given). Draws
come from ``numpy.random.default_rng(seed)``, one parameter after the other in name order,
so a spec names the same runs on any machine.
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
DRAW_KEYS = ('n', 'seed', 'parameters')
#: Distribution name -> (what its two numbers are, check of the two numbers).
DISTRIBUTIONS = {
    'uniform': ('[low, high] with low < high', lambda a, b: a < b),
    'normal': ('[mean, standard deviation] with standard deviation > 0', lambda a, b: b > 0),
}


class StudyError(ValueError):
    """A study spec is malformed; the message names the key and what is allowed."""


@dataclass(frozen=True)
class Run:
    """One run of a study: its position, its overrides, and which of them the study varies."""

    index: int
    overrides: dict
    #: The grid and draw values of this run (a subset of ``overrides``), for tables and plots.
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
        """Return the names of the grid and draw parameters, grid first, in spec order."""
        names = [k for product in self.grid for k in product]
        names += list((self.draws or {}).get('parameters', {}))
        return list(dict.fromkeys(names))

    def runs(self) -> list['Run']:
        """Return the study's runs: every grid point with every draw."""
        points = [dict(zip(product, values)) for product in self.grid
                  for values in itertools.product(*product.values())] or [{}]
        draws = self._draw_values()
        runs = []
        for point in points:
            for draw in draws:
                swept = {**point, **draw}
                runs.append(Run(len(runs), {**(self.parameters or {}), **swept}, swept))
        return runs

    def _draw_values(self):
        if not self.draws:
            return [{}]
        rng = np.random.default_rng(self.draws['seed'])
        n = self.draws['n']
        columns = {}
        for name in sorted(self.draws['parameters']):
            (kind, (a, b)), = self.draws['parameters'][name].items()
            values = rng.uniform(a, b, n) if kind == 'uniform' else rng.normal(a, b, n)
            columns[name] = [float(v) for v in values]
        return [{name: columns[name][i] for name in self.draws['parameters']}
                for i in range(n)]


def _number(value, where):
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


def _draws(value):
    value = _mapping(value, 'draws')
    _unknown(value, DRAW_KEYS, 'draws')
    for key in DRAW_KEYS:
        if key not in value:
            raise StudyError(f'draws: missing {key!r} (draws need n, seed and parameters)')
    n, seed = value['n'], value['seed']
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise StudyError(f'draws.n: expected an integer >= 1, got {n!r}')
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise StudyError(f'draws.seed: expected an integer >= 0, got {seed!r}')
    params = _mapping(value['parameters'], 'draws.parameters')
    if not params:
        raise StudyError('draws.parameters: no parameter to draw')
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
        meaning, ok = DISTRIBUTIONS[kind]
        if not isinstance(args, list) or len(args) != 2:
            raise StudyError(f'{where}.{kind}: expected {meaning}, got {args!r}')
        a, b = (_number(x, f'{where}.{kind}') for x in args)
        if not ok(a, b):
            raise StudyError(f'{where}.{kind}: expected {meaning}, got {args!r}')
        checked[name] = {kind: (a, b)}
    return {'n': n, 'seed': seed, 'parameters': checked}


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
    overlap = sorted(set(in_grid) & set((draws or {}).get('parameters', {})))
    if overlap:
        raise StudyError(f'{overlap}: a parameter is either on the grid or drawn, not both')
    clash = sorted(set(params) & (set(in_grid) | set((draws or {}).get('parameters', {}))))
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
