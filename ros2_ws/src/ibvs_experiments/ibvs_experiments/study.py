"""
Studies on Ray: every run of one or more study specs as a Ray task, cached, with a table.

Each run is ``ibvs run`` in a subprocess of a Ray worker, isolated from the others by its
own ``ROS_DOMAIN_ID`` (from a pool: :mod:`ibvs_bringup.domains`),
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and its own output directory. A run declares
``num_cpus=CPUS_PER_RUN`` to Ray: the lockstep passes one message at a time through the
graph's processes, so they take turns and one run keeps at most about one core busy
(each record's ``cpu_s`` says how much it used), and Ray runs as many at once as the machine
(or the cluster) has cores.

Without ``address`` a local Ray is started for the study (its temporary directory under
/tmp, removed afterwards) and shut down at the end; with ``address`` the runs go to an
existing cluster (``ray start --head`` / ``ray start --address=...``), whose workers must
have the workspace sourced and see the study directory at the same path (a shared file
system when the nodes are separate machines).

A finished run (succeeded, or failed with its logs) is recorded in ``<run dir>/run.json``
under a key that hashes the run's parameters, the scenario file and the code
(:func:`code_version`): a study started again skips what it finished. Ctrl-C cancels every
run (each stops its nodes as ``ibvs run`` does on SIGINT), shuts Ray down, and keeps the
records of the runs already finished.
"""

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
import hashlib
import importlib.util
import json
import logging
import math
import os
from pathlib import Path
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from typing import Any, TextIO

from ibvs_analysis import study_table
from ibvs_bringup import graph_params, scenario
from ibvs_bringup.domains import HELD_ENV, lock_domain, parse_pool, pool
from ibvs_common.process import supervised_child
import numpy as np

from . import study_spec
from .runner import EXIT_NODE_DIED, STALL_S

#: Cores one run keeps busy (the Ray resource each run task declares).
CPUS_PER_RUN = 1
#: Default pool of ROS_DOMAIN_IDs for the runs (inclusive): ``IBVS_ROS_DOMAINS``, else the
#: safe range 0-101 (:mod:`ibvs_bringup.domains`); the runs' locks keep them apart.
DOMAIN_IDS = pool()
#: The packages whose sources make up the code version of a run.
PACKAGES = ('ibvs_common', 'ibvs_model', 'ibvs_sim', 'ibvs_vision', 'ibvs_control',
            'ibvs_bringup', 'ibvs_analysis', 'ibvs_experiments')
#: Modules that organise runs but take no part in one: left out of the code version, so
#: that a change to the study or report layer keeps the runs cached.
NOT_IN_A_RUN = ('ibvs_experiments/study.py', 'ibvs_experiments/study_spec.py',
                'ibvs_experiments/report.py', 'ibvs_experiments/laws_report.py',
                'ibvs_experiments/bench.py', 'ibvs_experiments/tasks.py',
                'ibvs_analysis/study_table.py',
                # Draws tasks before the runs; a run gets the task's values as overrides,
                # which its key holds.
                'ibvs_model/task_sampler.py')
#: The niceness of Ray's workers, the runs': that of an ``ibvs run`` from a shell (0), not
#: Ray's default 15 (:class:`_Ray`). Ray's variable (ray/_private/ray_constants.py:
#: ``RAY_WORKER_NICENESS = "RAY_worker_niceness"``, Ray 2.60.0).
WORKER_NICENESS_ENV = 'RAY_worker_niceness'
WORKER_NICENESS = 0
#: Seconds a cancelled run gets to stop its nodes before Ray is shut down.
CANCEL_GRACE_S = 30.0


def code_version() -> str:
    """
    Return a hash of the installed sources (``*.py``) that take part in a run.

    The packages of :data:`PACKAGES`, by path, all but :data:`NOT_IN_A_RUN`.

    The same in a fresh clone, a colcon install and on every node of a cluster that runs
    the same code, and different as soon as one line changes: no git needed.
    """
    digest = hashlib.sha256()
    for package in PACKAGES:
        spec = importlib.util.find_spec(package)
        root = Path(next(iter(spec.submodule_search_locations)))
        for path in sorted(root.rglob('*.py')):
            if f'{package}/{path.relative_to(root)}' in NOT_IN_A_RUN:
                continue
            digest.update(f'{package}/{path.relative_to(root)}\0'.encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def parse_domains(text: str) -> tuple[int, int]:
    """Parse ``'LOW-HIGH'`` into the inclusive range of ROS_DOMAIN_IDs (within 0-101)."""
    try:
        return parse_pool(text)
    except ValueError as exc:
        raise study_spec.StudyError(str(exc)) from None


def execute_run(domains: tuple[int, int], run_dir: str | Path, scenario_name: str,
                overrides: Mapping[str, Any], duration_s: float, stall_s: float,
                figures: bool = False) -> dict[str, Any]:
    """
    Run ``ibvs run`` once in a subprocess on its own ROS domain; return what came of it.

    The domain is the first of ``domains`` (low, high) that no other run on this machine
    holds (:func:`ibvs_bringup.domains.lock_domain`). ``figures``: whether the run draws
    its figures (the spec's ``run_figures``; else ``ibvs run --no-figures``).

    A run whose node process died (exit code :data:`.runner.EXIT_NODE_DIED`) is run again,
    up to :data:`NODE_DEATH_ATTEMPTS` attempts in all (:func:`attempt_until_settled`).

    The body of the Ray task. Cancelled (KeyboardInterrupt from ``ray.cancel``), it sends
    SIGINT to the run, which stops its nodes cleanly, and waits for it.
    """
    import ray
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / 'metrics.json').unlink(missing_ok=True)  # from an earlier, failed attempt
    domain, lock = lock_domain(*domains)
    cmd = run_command(run_dir, scenario_name, overrides, duration_s, stall_s, figures)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED='1',
               **{HELD_ENV: str(domain)},
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    try:
        record = attempt_until_settled(cmd, env, run_dir)
    finally:
        lock.close()
    record.update(domain_id=domain, host=os.uname().nodename,
                  niceness=os.getpriority(os.PRIO_PROCESS, 0),
                  ray_node=ray.get_runtime_context().get_node_id()
                  if ray.is_initialized() else None)
    return record


def run_command(run_dir: str | Path, scenario_name: str, overrides: Mapping[str, Any],
                duration_s: float | None, stall_s: float, figures: bool = False) -> list[str]:
    """
    Return the ``ibvs run`` command line of a study run (:func:`execute_run`).

    Each override is written as YAML 1.1 text (:func:`.study_spec.yaml_value`), which the
    run's ``-p`` reads back (:func:`ibvs_bringup.scenario.parse_override`) as the value
    drawn: ``json.dumps(-1e-05)`` would reach the run as the string '-1e-05'.
    """
    cmd = [sys.executable, '-m', 'ibvs_experiments.cli', 'run', scenario_name, '-o', str(run_dir),
           '--stall-s', repr(float(stall_s))] + ([] if figures else ['--no-figures'])
    if duration_s is not None:
        cmd += ['--duration', repr(float(duration_s))]
    for name, value in overrides.items():
        cmd += ['-p', f'{name}:={study_spec.yaml_value(value)}']
    return cmd


#: Attempts of a run whose node process died. A run is deterministic, so a death of ours (an
#: exception in a node) comes back the same on the second attempt, and costs one run more;
#: a crash below us need not (the machine, or one of the native libraries the nodes load:
#: Mesa's EGL and llvmpipe under the renderer, PyBullet, OpenCV, the DDS), and the second
#: attempt tells the two apart.
NODE_DEATH_ATTEMPTS = 2


def attempt_until_settled(cmd: Sequence[str], env: Mapping[str, str], run_dir: Path,
                          attempts: int = NODE_DEATH_ATTEMPTS) -> dict[str, Any]:
    """
    Run ``cmd`` (an ``ibvs run`` into ``run_dir``) until it ends other than by a node's death.

    At most ``attempts`` times; an attempt that ends with :data:`.runner.EXIT_NODE_DIED`
    before the last keeps its log as ``runner.attempt<N>.log`` and its nodes' logs as
    ``logs.attempt<N>/``. Returns the record: ``exit_code``, ``wall_s`` and ``cpu_s`` (all
    attempts), ``command``, ``attempts``, ``earlier_failures`` (the reason of each attempt
    that was run again), and ``status`` 'ok' with ``metrics`` or 'failed' with ``reason``.
    """
    # An earlier study's attempts of this run (--retry-failed) make way for this one's.
    for old in run_dir.glob('logs.attempt*'):
        shutil.rmtree(old)
    for old in run_dir.glob('runner.attempt*.log'):
        old.unlink()
    start = time.monotonic()
    cpu_start = _children_cpu_s()
    earlier = []
    for attempt in range(1, attempts + 1):
        code = _attempt(cmd, env, run_dir)
        if code != EXIT_NODE_DIED or attempt == attempts:
            break
        earlier.append(_failure_reason(run_dir))
        os.replace(run_dir / 'runner.log', run_dir / f'runner.attempt{attempt}.log')
        if (run_dir / 'logs').is_dir():
            os.replace(run_dir / 'logs', run_dir / f'logs.attempt{attempt}')
    # The run and its nodes are waited for, so their CPU time rolls up to this worker.
    record = {'exit_code': code, 'wall_s': time.monotonic() - start,
              'cpu_s': _children_cpu_s() - cpu_start, 'command': list(cmd),
              'attempts': attempt, 'earlier_failures': earlier}
    metrics_path = run_dir / 'metrics.json'
    if code == 0 and metrics_path.is_file():
        record.update(status='ok', metrics=json.loads(metrics_path.read_text()))
    else:
        record.update(status='failed', metrics=None, reason=_failure_reason(run_dir))
    return record


def _attempt(cmd, env, run_dir):
    """Run ``cmd`` once, its output into ``run_dir``/runner.log; return its exit code."""
    with open(run_dir / 'runner.log', 'wb') as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, env=env,
                                preexec_fn=supervised_child)
        try:
            return proc.wait()
        except KeyboardInterrupt:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(CANCEL_GRACE_S - 5.0)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
            raise


def _failure_reason(run_dir):
    """Return why a run failed, from its runner.log (its error lines, else its last three)."""
    text = (Path(run_dir) / 'runner.log').read_text(errors='replace').splitlines()
    why = [line for line in text if line.startswith(('run failed', 'run stalled', 'error', '  '))
           and not line.startswith('  [')]
    return ' '.join(x.strip() for x in (why or text[-3:]))[:2000]


def _children_cpu_s():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_label(record: Mapping[str, Any]) -> str:
    """Return a run's name in progress lines: ``<study>#<index> (<swept>=<value>, ...)``."""
    swept = record.get('swept') or {}
    values = ', '.join(f'{name}={value:g}' if isinstance(value, float) else f'{name}={value}'
                       for name, value in swept.items())
    return f"{record['study']}#{record['index']}" + (f' ({values})' if values else '')


class Progress:
    """
    One line per finished run: count, share, failures, elapsed time and ETA.

    The ETA is the mean wall time of the runs finished in this session (each run's own,
    from its start to its end: not the Ray session's start-up, nor the wait in Ray's queue)
    times the rounds of ``parallel`` runs at once that are left. The first ETA of a
    ``make report`` once said 72:45 for a run of 26:49: it was the elapsed time, start-up
    included, per run finished, as if the runs went one at a time.
    """

    def __init__(self, total: int, cached: int, out: TextIO = sys.stdout,
                 parallel: int = 1) -> None:
        """Count ``total`` runs of which ``cached`` are done already, ``parallel`` at once."""
        self.total, self.done, self.failed, self.cached = total, cached, 0, cached
        self.start = time.monotonic()
        self.out = out
        self.parallel = max(1, int(parallel))
        self.walls = []

    def eta(self) -> float:
        """Return the wall seconds the runs left should take (NaN before the first's end)."""
        if not self.walls:
            return float('nan')
        rounds = math.ceil((self.total - self.done) / self.parallel)
        return float(np.mean(self.walls)) * rounds

    def update(self, label: str, record: Mapping[str, Any]) -> None:
        """Account for one finished run and print the line."""
        self.done += 1
        self.failed += record['status'] != 'ok'
        elapsed = time.monotonic() - self.start
        if record.get('wall_s') is not None:
            self.walls.append(float(record['wall_s']))
        eta = self.eta()
        width = 20
        filled = int(round(width * self.done / max(self.total, 1)))
        result = (f"{1e3 * record['metrics']['final_position_error_m']:.3f} mm"
                  if record['status'] == 'ok' else 'FAILED')
        again = ''.join(f'\n    attempt {i} of {label}, run again: a node died: {why}'
                        for i, why in enumerate(record.get('earlier_failures') or (), 1))
        print(f"[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} "
              f'({self.failed} failed, {self.cached} cached)  elapsed {_clock(elapsed)}  '
              f'ETA {_clock(eta)}  {label}: {result}{again}', file=self.out, flush=True)


def _clock(seconds):
    if not np.isfinite(seconds):
        return '--:--'
    minutes, seconds = divmod(int(round(seconds)), 60)
    return f'{minutes}:{seconds:02d}'


class _Ray:
    """Ray for the length of a study: a local one started here, or a cluster joined."""

    def __init__(self, address, parallel):
        self.address, self.parallel = address, parallel
        self.temp_dir = None

    def __enter__(self):
        import ray
        os.environ.setdefault('RAY_USAGE_STATS_ENABLED', '0')
        # Ray starts its workers at nice 15 (RAY_CONFIG(int, worker_niceness, 15),
        # src/ray/common/ray_config_def.h), read from RAY_worker_niceness when the raylet
        # starts: a study's runs then yield the CPU to everything else and a free-running
        # run (which keeps wall time) starves. A worker cannot lower its own niceness
        # (setpriority needs CAP_SYS_NICE to go below the current value), so it is set here,
        # for the local Ray this process starts; a cluster's `ray start` needs it in its
        # environment (docs/studies.md).
        os.environ.setdefault(WORKER_NICENESS_ENV, str(WORKER_NICENESS))
        quiet = {'include_dashboard': False, 'log_to_driver': False,
                 'logging_level': logging.ERROR, 'configure_logging': True}
        if self.address:
            ray.init(address=self.address, **quiet)
        else:
            self.temp_dir = tempfile.mkdtemp(prefix='ibvs-ray-')
            ray.init(num_cpus=self.parallel * CPUS_PER_RUN, _temp_dir=self.temp_dir,
                     object_store_memory=100 * 2 ** 20, **quiet)
        return ray

    def __exit__(self, *exc):
        import ray
        ray.shutdown()
        if self.temp_dir:
            shutil.rmtree(self.temp_dir, ignore_errors=True)
        return False


def default_parallel() -> int:
    """Return how many runs fit at once on this machine (cores / CPUS_PER_RUN, at least 1)."""
    return max(1, (os.cpu_count() or 1) // CPUS_PER_RUN)


def check_spec(spec: study_spec.Spec) -> None:
    """
    Raise :class:`scenario.ScenarioError` unless every run of ``spec`` can start.

    Each run's parameters (its scenario's, the spec's ``parameters``, its grid point and
    draws) are checked as ``ibvs run`` checks them (:func:`graph_params.check`): the nodes'
    declared names and ranges, and the rules between parameters
    (:func:`graph_params.check_rules`).
    """
    base = scenario.load_parameters(spec.scenario)
    for run in spec.runs():
        where = f'study {spec.name}, run {run.index}'
        try:
            graph_params.check({**base, **run.overrides}, where)
            graph_params.check_rules({**base, **run.overrides}, where)
        except scenario.ScenarioError as exc:
            # Name where in the spec the refused value comes from (a grid, a draw, a task).
            named = [name for name in run.overrides if f"'{name}'" in str(exc)]
            if not named:
                raise
            raise scenario.ScenarioError(
                f"{exc} (from the spec's {spec.origin(named[0])})") from None


@dataclass(frozen=True)
class Job:
    """
    Work beside the runs, on their Ray session and its cores: ``func(*args)`` on one core.

    ``func``: a Python function that Ray can import by name. What a report computes
    without a graph (the law study's model-only sweeps) then runs among the graph runs
    instead of after them, when Ray finds a core free (Ray queues each kind of task on its
    own: a job may start before runs submitted earlier). ``done`` gets its answer in the
    driver.
    """

    name: str
    func: Callable[..., Any]
    args: tuple = ()
    done: Callable[[Any], None] = lambda result: None


def run_studies(specs: Sequence[study_spec.Spec], out_dir: Path, address: str | None = None,
                parallel: int | None = None, domains: tuple[int, int] = DOMAIN_IDS,
                stall_s: float = STALL_S, retry_failed: bool = False,
                out: TextIO = sys.stdout, jobs: Sequence[Job] = (),
                on_record: Callable[[Mapping[str, Any]], None] | None = None
                ) -> dict[str, list[dict[str, Any]]]:
    """
    Run every run of ``specs`` (a list of :class:`study_spec.Spec`) in one Ray session.

    Each study writes into ``<out_dir>/<name>/``: ``runs/<key>/`` per run (``ibvs run``'s
    output, ``runner.log``, ``run.json``), ``table.csv``, ``table.md`` and its figures
    (:func:`ibvs_analysis.study_table.write_results`).
    Returns ``{name: [record, ...]}`` in run order. Runs recorded under the same key are not
    run again (failed ones are with ``retry_failed``). Every run's parameters are checked
    first (:func:`check_spec`): a spec with a name no node declares or a value out of range
    runs nothing.

    ``jobs`` (:class:`Job`) run on the same session after the runs are submitted (in this
    process when every run is cached). ``on_record``: called in this process with each
    run's record as it finishes, while the others run (cached ones first), so that reading
    a run's output back overlaps with the runs still going. A job's exception is raised
    once every run has finished.
    """
    for spec in specs:
        check_spec(spec)
    records, todo = plan(specs, out_dir, retry_failed)
    cached = sum(len(r) for r in records.values()) - len(todo)
    total = cached + len(todo)
    print(f'{total} runs in {len(specs)} stud{"y" if len(specs) == 1 else "ies"}: '
          f'{cached} cached, {len(todo)} to run'
          + (f'; {len(jobs)} job(s) beside them' if jobs else ''), file=out, flush=True)
    if on_record is not None:
        for spec in specs:
            for record in records[spec.name]:
                if record.get('cached'):
                    on_record(record)
    if todo:
        _execute(todo, address, parallel or default_parallel(), domains, stall_s,
                 Progress(total, cached, out, parallel or default_parallel()), jobs,
                 on_record)
    else:
        for job in jobs:
            job.done(job.func(*job.args))
    for spec in specs:
        study_table.write_results(spec, records[spec.name], out_dir / spec.name)
    return records


def plan(specs: Sequence[study_spec.Spec], out_dir: str | Path, retry_failed: bool = False
         ) -> tuple[dict[str, list[dict[str, Any]]],
                    list[tuple[study_spec.Spec, dict[str, Any]]]]:
    """
    Return ``({name: [record, ...]}, [(spec, record), ...])``: every run, and those to run.

    A run whose ``run.json`` holds the same key is taken from there (``cached``), unless it
    failed and ``retry_failed`` is set.
    """
    out_dir = Path(out_dir)
    version = code_version()
    todo, records = [], {}
    for spec in specs:
        base = scenario.load_parameters(spec.scenario)
        study_dir = out_dir / spec.name
        records[spec.name] = []
        for run in spec.runs():
            key = study_spec.run_key(base, run.overrides, spec.duration_s, version)
            run_dir = study_dir / 'runs' / key[:16]
            record = {'study': spec.name, 'index': run.index, 'key': key,
                      'swept': run.swept, 'overrides': run.overrides,
                      'run_dir': str(run_dir)}
            previous = _load_record(run_dir, key)
            if previous and (previous['status'] == 'ok' or not retry_failed):
                record.update({k: v for k, v in previous.items() if k not in record},
                              cached=True)
            else:
                todo.append((spec, record))
            records[spec.name].append(record)
    return records, todo


def _execute(todo, address, parallel, domains, stall_s, progress, jobs=(), on_record=None):
    with _Ray(address, parallel) as ray:
        task = ray.remote(execute_run).options(num_cpus=CPUS_PER_RUN, max_retries=0)
        refs = {}
        for spec, record in todo:
            ref = task.remote(domains, record['run_dir'], spec.scenario, record['overrides'],
                              spec.duration_s, stall_s, spec.run_figures)
            refs[ref] = record
        job_refs = {ray.remote(job.func).options(num_cpus=1, max_retries=0).remote(*job.args):
                    (job, time.monotonic()) for job in jobs}
        pending = list(refs) + list(job_refs)
        failure = None
        try:
            while pending:
                ready, pending = ray.wait(pending, num_returns=1, timeout=1.0)
                for ref in ready:
                    if ref in job_refs:
                        job, submitted = job_refs[ref]
                        try:
                            job.done(ray.get(ref))
                        except Exception as exc:  # raised below, once the runs are done
                            failure = failure or exc
                        print(f'  job {job.name}: done {_clock(time.monotonic() - submitted)} '
                              'after it was submitted', file=progress.out, flush=True)
                        continue
                    record = refs[ref]
                    try:
                        result = ray.get(ref)
                    except ray.exceptions.RayError as exc:
                        result = {'status': 'failed', 'metrics': None,
                                  'reason': f'Ray task failed: {exc}'[:2000]}
                    record.update(result, cached=False)
                    Path(record['run_dir'], 'run.json').write_text(
                        json.dumps(record, indent=2, default=str) + '\n')
                    progress.update(run_label(record), record)
                    if on_record is not None:
                        on_record(record)
        except KeyboardInterrupt:
            print(f'\ninterrupted: stopping {len(pending)} runs (finished runs stay cached)',
                  file=progress.out, flush=True)
            for ref in pending:
                ray.cancel(ref)
            ray.wait(pending, num_returns=len(pending), timeout=CANCEL_GRACE_S)
            raise
        if failure is not None:
            raise failure


def _load_record(run_dir, key):
    path = Path(run_dir) / 'run.json'
    try:
        record = json.loads(path.read_text())
    except (FileNotFoundError, ValueError):
        return None
    return record if record.get('key') == key and 'status' in record else None


def study_path(name_or_path: str | Path) -> Path:
    """Return the spec file of an installed study name ('fig13_link_lengths') or a path."""
    path = Path(name_or_path)
    if path.suffix in ('.yaml', '.yml'):
        if not path.is_file():
            raise study_spec.StudyError(f'study spec {path} does not exist')
        return path
    directory = scenario.share_directory('ibvs_experiments') / 'studies'
    candidate = directory / f'{name_or_path}.yaml'
    if not candidate.is_file():
        known = sorted(p.stem for p in directory.glob('*.yaml'))
        raise study_spec.StudyError(f'unknown study {name_or_path!r}; known: {known}')
    return candidate
