"""Study specs: checking, expansion into runs, seeded draws and cache keys (no rclpy, no Ray)."""

from ibvs_experiments import study_spec
from ibvs_experiments.study_spec import parse, run_key, StudyError
import numpy as np
import pytest

BASE = {'scenario': 'scenario1'}


def test_no_grid_no_draws_is_one_run_with_the_fixed_parameters():
    runs = parse({**BASE, 'parameters': {'actuators': 'limited'}}).runs()
    assert [(r.overrides, r.swept) for r in runs] == [({'actuators': 'limited'}, {})]


def test_grid_is_the_product_and_a_list_of_grids_their_union():
    product = parse({**BASE, 'grid': {'a': [1, 2, 3], 'b': ['x', 'y']}}).runs()
    assert len(product) == 6
    assert {(r.swept['a'], r.swept['b']) for r in product} == \
        {(a, b) for a in (1, 2, 3) for b in 'xy'}
    union = parse({**BASE, 'grid': [{'a': [1, 2]}, {'b': [3]}]}).runs()
    assert [r.swept for r in union] == [{'a': 1}, {'a': 2}, {'b': 3}]
    assert [r.index for r in union] == [0, 1, 2]


def test_draws_are_seeded_in_range_and_combined_with_every_grid_point():
    data = {**BASE, 'grid': {'g': [0, 1]},
            'draws': {'n': 50, 'seed': 7, 'parameters': {
                'u': {'uniform': [2.0, 3.0]}, 'n': {'normal': [10.0, 0.5]}}}}
    runs = parse(data).runs()
    assert len(runs) == 100
    u = np.array([r.swept['u'] for r in runs])
    assert np.all((u >= 2.0) & (u < 3.0))
    assert [r.swept['u'] for r in runs[:50]] == [r.swept['u'] for r in runs[50:]]
    assert [r.overrides for r in parse(data).runs()] == [r.overrides for r in runs]
    other = parse({**data, 'draws': {**data['draws'], 'seed': 8}}).runs()
    assert [r.swept['n'] for r in other] != [r.swept['n'] for r in runs]
    assert all(isinstance(r.swept['n'], float) for r in runs)


@pytest.mark.parametrize('data, names', [
    ({**BASE, 'grids': {}}, ['grids', 'allowed']),
    ({'grid': {'a': [1]}}, ['scenario']),
    ({**BASE, 'grid': {'a': 1}}, ['grid.a', 'non-empty list']),
    ({**BASE, 'grid': {'a': []}}, ['grid.a']),
    ({**BASE, 'duration_s': -1}, ['duration_s']),
    ({**BASE, 'draws': {'n': 3, 'parameters': {'a': {'uniform': [0, 1]}}}}, ['seed']),
    ({**BASE, 'draws': {'n': 0, 'seed': 1, 'parameters': {'a': {'uniform': [0, 1]}}}},
     ['draws.n']),
    ({**BASE, 'draws': {'n': 2, 'seed': 1, 'parameters': {'a': {'gamma': [1, 1]}}}},
     ['draws.parameters.a', "'gamma'", 'uniform', 'normal']),
    ({**BASE, 'draws': {'n': 2, 'seed': 1, 'parameters': {'a': {'uniform': [1, 0]}}}},
     ['draws.parameters.a.uniform', 'low < high']),
    ({**BASE, 'draws': {'n': 2, 'seed': 1, 'parameters': {'a': {'normal': [0, -1]}}}},
     ['standard deviation > 0']),
    ({**BASE, 'draws': {'n': 2, 'seed': 1, 'parameters': {'a': {'normal': [0]}}}},
     ['draws.parameters.a.normal']),
    ({**BASE, 'draws': {'n': 2, 'seed': 1, 'rate': 3,
                        'parameters': {'a': {'normal': [0, 1]}}}}, ['rate']),
    ({**BASE, 'grid': {'a': [1]},
      'draws': {'n': 2, 'seed': 1, 'parameters': {'a': {'normal': [0, 1]}}}}, ["'a'"]),
    ({**BASE, 'parameters': {'a': 1}, 'grid': {'a': [1, 2]}}, ["'a'", 'not both']),
    ({**BASE, 'run_figures': 'yes'}, ['run_figures', 'true or false']),
])
def test_a_bad_spec_is_refused_naming_the_key(data, names):
    with pytest.raises(StudyError) as info:
        parse(data)
    for name in names:
        assert name in str(info.value)


def test_load_names_the_file(tmp_path):
    path = tmp_path / 'bad.yaml'
    path.write_text('scenario: scenario1\nsweep: {a: [1]}\n')
    with pytest.raises(StudyError, match='bad.yaml.*sweep'):
        study_spec.load(path)
    path.write_text('scenario: scenario1\n')
    assert study_spec.load(path).name == 'bad'


def test_run_key_changes_with_each_input_and_not_with_dict_order():
    key = run_key({'x': 1, 'y': 2}, {'a': 0.5}, 1.0, 'v1')
    assert key == run_key({'y': 2, 'x': 1}, {'a': 0.5}, 1.0, 'v1')
    others = [run_key({'x': 1, 'y': 3}, {'a': 0.5}, 1.0, 'v1'),
              run_key({'x': 1, 'y': 2}, {'a': 0.6}, 1.0, 'v1'),
              run_key({'x': 1, 'y': 2}, {'a': 0.5}, 2.0, 'v1'),
              run_key({'x': 1, 'y': 2}, {'a': 0.5}, 1.0, 'v2')]
    assert len({key, *others}) == 5


def test_installed_study_specs_are_valid():
    from pathlib import Path
    for path in (Path(__file__).resolve().parents[1] / 'studies').glob('*.yaml'):
        assert study_spec.load(path).runs()


def test_domain_locks_are_exclusive_and_released():
    from ibvs_bringup.domains import lock_domain
    first, lock1 = lock_domain(195, 196)
    second, lock2 = lock_domain(195, 196)
    assert first != second and {first, second} == {195, 196}
    lock1.close()
    again, lock3 = lock_domain(195, 196)
    assert again == first
    lock2.close()
    lock3.close()


def test_a_run_claims_a_free_domain_or_refuses_a_busy_one():
    """Two runs never share a domain: unset takes the next free, a busy explicit one stops."""
    import pytest
    from ibvs_bringup.domains import claim, DomainBusy, HELD_ENV, lock_domain
    first, lock1 = claim({}, pool=(197, 198))
    second, lock2 = claim({}, pool=(197, 198))
    assert (first, second) == (197, 198)
    with pytest.raises(DomainBusy, match='every ROS domain'):
        claim({}, pool=(197, 198))
    # An explicit ROS_DOMAIN_ID must be one ROS may use (0-101): one no other run holds.
    mine, lock4 = lock_domain(0, 101)
    with pytest.raises(DomainBusy, match=f'ROS_DOMAIN_ID={mine} is used by another run'):
        claim({'ROS_DOMAIN_ID': str(mine)})
    # A study's run: the parent holds the lock and says so.
    assert claim({'ROS_DOMAIN_ID': str(mine), HELD_ENV: str(mine)}) == (mine, None)
    lock4.close()
    again, lock3 = claim({'ROS_DOMAIN_ID': str(mine)})
    assert again == mine
    for lock in (lock1, lock2, lock3):
        lock.close()


def test_a_held_domain_is_released_and_the_environment_restored_even_on_error():
    import pytest
    from ibvs_bringup.domains import held
    environ = {}
    with pytest.raises(RuntimeError):
        with held(environ, pool=(196, 196)) as (domain, chosen):
            assert (domain, chosen) == (196, True) and environ['ROS_DOMAIN_ID'] == '196'
            raise RuntimeError('a node failed to start')
    assert environ == {}
    with held(environ, pool=(196, 196)) as (domain, _):  # free again
        assert domain == 196


def test_run_figures_are_off_unless_asked():
    from pathlib import Path
    assert parse(dict(BASE)).run_figures is False
    assert parse({**BASE, 'run_figures': True}).run_figures is True
    # The report shows the scenario runs' own figures; its other studies need none.
    studies = Path(__file__).resolve().parents[1] / 'studies'
    assert all(study_spec.load(studies / f'scenario{n}.yaml').run_figures for n in (1, 2, 3))
    assert not study_spec.load(studies / 'fig13_link_lengths.yaml').run_figures
