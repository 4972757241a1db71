"""
Write a versioned task set of the workspace sampler to a file: JSON or CSV.

``python -m ibvs_experiments.tasks -n 500 --seed 1 -o tasks.json`` writes
:func:`ibvs_model.task_sampler.tasks` (500, 1) of workspace-2; ``--version workspace-3``
draws them with the rendered line-of-sight check (:mod:`.line_of_sight`, a few hundredths
of a second a target, its progress on stderr) and the observability bound of
``--teach-frames`` (10). JSON as ``{'definition': ..., 'tasks':
[...]}`` (the sampler's version, box and margins, then one dict per task); CSV as one row
per task, the vectors as JSON lists, the version in a column. The same (version, n, seed)
writes the same tasks on any machine; a study draws them with ``draws.task``
(docs/studies.md).
"""

import argparse
from collections import Counter
import csv
import json
from pathlib import Path
import sys
import time

from ibvs_model import task_sampler

#: CSV columns, in this order.
COLUMNS = ('id', 'version', 'seed', 'index', 'observability', 'jacobian_sigma5',
           'start_joints', 'target_position', 'target_rotation', 'target_joints')


def draw(n: int, seed: int, version: str = task_sampler.VERSION, teach_frames: int = 10,
         tally: 'Counter[str] | None' = None) -> list[dict]:
    """Return ``n`` tasks of ``seed`` and ``version`` (workspace-3: rendered line of sight)."""
    if version == task_sampler.VERSION:
        return task_sampler.tasks(n, seed, tally=tally)
    from .line_of_sight import RenderedLineOfSight
    tally = Counter() if tally is None else tally
    started = time.monotonic()
    with RenderedLineOfSight() as seen:
        def check(q):
            why = seen(q)
            kept = tally['kept'] + (why is None)
            if why is None and kept % 50 == 0:
                elapsed = time.monotonic() - started
                print(f'{kept} of {n} tasks, {seen.checked} targets rendered, '
                      f'{elapsed:.0f} s, about {elapsed * (n - kept) / kept:.0f} s to go',
                      file=sys.stderr, flush=True)
            return why
        return task_sampler.tasks(n, seed, version=version, line_of_sight=check,
                                  teach_frames=teach_frames, tally=tally)


def write(path: str | Path, n: int, seed: int, version: str = task_sampler.VERSION,
          teach_frames: int = 10) -> list[dict]:
    """Write ``n`` tasks of ``seed`` and ``version`` to ``path`` (.json or .csv); return them."""
    path = Path(path)
    if path.suffix not in ('.json', '.csv'):
        raise ValueError(f'{path}: the file must end in .json or .csv')
    tasks = draw(n, seed, version, teach_frames)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix == '.json':
        margins = task_sampler.margins_for(version, teach_frames)
        path.write_text(json.dumps({'definition': {**task_sampler.describe(margins, version),
                                                   'n': n, 'seed': seed},
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
    parser.add_argument('--version', choices=task_sampler.VERSIONS,
                        default=task_sampler.VERSION, help='the sampler version (default '
                        f'{task_sampler.VERSION}; workspace-3 renders each target)')
    parser.add_argument('--teach-frames', type=int, default=10,
                        help="workspace-3: the teach's frames, which set the observability "
                        'bound (default 10)')
    args = parser.parse_args(argv)
    try:
        tasks = write(args.out, args.n, args.seed, args.version, args.teach_frames)
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(f'wrote {len(tasks)} tasks of {args.version} (seed {args.seed}) to '
          f'{args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
