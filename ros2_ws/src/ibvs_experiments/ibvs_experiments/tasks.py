"""
Write a versioned task set of the workspace sampler to a file: JSON or CSV.

``python -m ibvs_experiments.tasks -n 500 --seed 1 -o tasks.json`` writes
:func:`ibvs_model.task_sampler.tasks` (500, 1): JSON as ``{'definition': ..., 'tasks':
[...]}`` (the sampler's version, box and margins, then one dict per task); CSV as one row
per task, the vectors as JSON lists, the version in a column. The same (version, n, seed)
writes the same tasks on any machine; a study draws them with ``draws.task``
(docs/studies.md).
"""

import argparse
import csv
import json
from pathlib import Path
import sys

from ibvs_model import task_sampler

#: CSV columns, in this order.
COLUMNS = ('id', 'version', 'seed', 'index', 'observability', 'jacobian_sigma5',
           'start_joints', 'target_position', 'target_rotation', 'target_joints')


def write(path: str | Path, n: int, seed: int) -> list[dict]:
    """Write ``n`` tasks of ``seed`` to ``path`` (.json or .csv) and return them."""
    path = Path(path)
    if path.suffix not in ('.json', '.csv'):
        raise ValueError(f'{path}: the file must end in .json or .csv')
    tasks = task_sampler.tasks(n, seed)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix == '.json':
        path.write_text(json.dumps({'definition': {**task_sampler.describe(), 'n': n,
                                                   'seed': seed},
                                    'tasks': tasks}, indent=1) + '\n')
    else:
        with open(path, 'w', newline='') as f:
            writer = csv.DictWriter(f, fieldnames=list(COLUMNS))
            writer.writeheader()
            for task in tasks:
                writer.writerow({k: json.dumps(v) if isinstance(v, list) else v
                                 for k, v in task.items() if k in COLUMNS})
    return tasks


def main(argv: list[str] | None = None) -> int:
    """Parse the command line and write the task set."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[1].strip())
    parser.add_argument('-n', type=int, default=500, help='how many tasks (default 500)')
    parser.add_argument('--seed', type=int, default=1, help='the seed (default 1)')
    parser.add_argument('-o', '--out', default='tasks.json', help='a .json or .csv file')
    args = parser.parse_args(argv)
    try:
        tasks = write(args.out, args.n, args.seed)
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(f'wrote {len(tasks)} tasks of {task_sampler.VERSION} (seed {args.seed}) to '
          f'{args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
