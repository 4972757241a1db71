"""The output folder rule of ibvs run and ibvs cell: only a run's folder, never through a link."""

import json
import os

from ibvs_experiments import output_dir, runner
from ibvs_experiments.output_dir import claim, MARKER, OutputRefused, STUDY_COMPANIONS
import pytest


def test_a_symlinked_folder_is_refused_and_what_it_points_to_survives(tmp_path):
    target = tmp_path / 'elsewhere'
    (target / 'bag').mkdir(parents=True)
    (target / 'bag' / 'x').write_text('precious')
    link = tmp_path / 'link'
    link.symlink_to(target)
    with pytest.raises(OutputRefused, match='symbolic link'):
        claim(link)
    assert (target / 'bag' / 'x').read_text() == 'precious'
    assert not (target / MARKER).exists()


def test_a_folder_of_other_files_is_refused_untouched(tmp_path):
    (tmp_path / 'bag').mkdir()
    (tmp_path / 'bag' / 'x').write_text('mine')
    (tmp_path / 'notes.txt').write_text('mine')
    with pytest.raises(OutputRefused, match=r'holds files that no run wrote \(bag, notes.txt'):
        claim(tmp_path, STUDY_COMPANIONS)
    assert sorted(os.listdir(tmp_path)) == ['bag', 'notes.txt']
    assert (tmp_path / 'bag' / 'x').read_text() == 'mine'


def test_a_new_empty_or_study_folder_is_taken_and_marked(tmp_path):
    for folder, companions in ((tmp_path / 'new' / 'run', ()),
                               (tmp_path / 'study', STUDY_COMPANIONS)):
        folder.mkdir(parents=True, exist_ok=bool(companions))
        if companions:
            (folder / 'runner.log').write_text('the study writes it before the run')
        held = claim(folder, companions, command=['ibvs', 'run', 'scenario1'])
        said = json.loads((folder / MARKER).read_text())
        assert said == {'pid': os.getpid(), 'command': 'ibvs run scenario1'}
        held.release()
    assert (tmp_path / 'study' / 'runner.log').exists()


def test_a_previous_runs_folder_loses_only_what_a_run_replaces(tmp_path):
    claim(tmp_path).release()
    (tmp_path / 'bag').mkdir()
    (tmp_path / 'bag' / 'bag.mcap').write_bytes(b'old')
    (tmp_path / 'metrics.json').write_text('{}')
    (tmp_path / 'notes.txt').write_text('kept')
    outside = tmp_path.parent / f'{tmp_path.name}-outside'
    outside.mkdir()
    (outside / 'x').write_text('kept')
    (tmp_path / 'metrics.json').unlink()
    (tmp_path / 'metrics.json').symlink_to(outside / 'x')  # a link is removed, not followed
    held = claim(tmp_path)
    held.remove(runner.REPLACED)
    held.release()
    assert sorted(os.listdir(tmp_path)) == [MARKER, 'notes.txt']
    assert (outside / 'x').read_text() == 'kept'


def test_a_folder_in_use_is_refused_naming_its_run_until_it_ends(tmp_path):
    first = claim(tmp_path, command=['ibvs', 'run', 'scenario1', '-o', str(tmp_path)])
    with pytest.raises(OutputRefused) as refused:
        claim(tmp_path)
    assert f'in use by another run (pid {os.getpid()}, command line: ibvs run scenario1 -o ' \
           f'{tmp_path})' in str(refused.value)
    first.release()
    claim(tmp_path).release()


def test_a_folder_that_cannot_be_made_is_said_in_words(tmp_path):
    with pytest.raises(OutputRefused, match='cannot create or read the output folder /proc/x: '
                       'No such file or directory'):
        claim('/proc/x')
    (tmp_path / 'file').write_text('')
    with pytest.raises(OutputRefused, match='is not a folder'):
        claim(tmp_path / 'file')


def test_a_refused_start_removes_only_the_folder_it_made(tmp_path):
    made = claim(tmp_path / 'session')
    (made.path / 'params.yaml').write_text('')
    made.release(('params.yaml', 'logs'))
    assert not (tmp_path / 'session').exists()
    kept = claim(tmp_path)  # there before: nothing of it goes
    (tmp_path / 'params.yaml').write_text('')
    kept.release(('params.yaml', 'logs'))
    assert sorted(os.listdir(tmp_path)) == [MARKER, 'params.yaml']


def test_prepare_holds_the_folder_and_refuses_a_foreign_one(tmp_path):
    run = runner.prepare('scenario1', tmp_path / 'run', duration_s=0.1)
    try:
        with pytest.raises(output_dir.OutputRefused, match='in use by another run'):
            runner.prepare('scenario1', tmp_path / 'run', duration_s=0.1)
    finally:
        run.claim.release()
    (tmp_path / 'mine').mkdir()
    (tmp_path / 'mine' / 'bag').mkdir()
    with pytest.raises(output_dir.OutputRefused):
        runner.prepare('scenario1', tmp_path / 'mine', duration_s=0.1)
    assert os.listdir(tmp_path / 'mine') == ['bag']
