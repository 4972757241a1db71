"""What ``ibvs`` says of itself: its commands, the real_cell scenario, the cell's domain."""

from pathlib import Path
import re

from ibvs_bringup import domains
from ibvs_experiments import cli
import pytest

README = Path(__file__).resolve().parents[4] / 'README.md'


def usage(capsys, *argv):
    """Return what ``ibvs ARGV --help`` prints."""
    with pytest.raises(SystemExit):
        cli.main([*argv, '--help'])
    return capsys.readouterr().out


def test_the_readmes_help_line_names_every_command(capsys):
    commands = re.search(r'usage: ibvs \[-h\]\s+\{([a-z,]+)\}', usage(capsys)).group(1)
    if not README.exists():
        pytest.skip('not in the source tree')
    line = re.search(r'^ibvs --help +# (.*)$', README.read_text(), re.MULTILINE).group(1)
    assert line.split(', ') == commands.split(',')


def test_run_says_real_cell_is_simulated(capsys):
    text = ' '.join(usage(capsys, 'run').split())
    assert 'real_cell (a real cell simulated' in text
    assert 'the real arm and camera' not in text


def test_the_cells_domain_refusals_name_its_domain_not_a_free_one(monkeypatch, tmp_path,
                                                                  capsys):
    monkeypatch.setenv(domains.DOMAIN_ENV, '-1')
    assert cli.main(['cell', '-o', str(tmp_path / 'bad')]) == 2
    err = capsys.readouterr().err
    assert "ROS_DOMAIN_ID='-1' is not a ROS domain" in err
    assert "(unset: ROS's default 0), never a free one" in err and 'first free' not in err
    # A domain that another run on this machine holds.
    domain, lock = domains.lock_domain(*domains.SAFE_RANGE)
    try:
        monkeypatch.setenv(domains.DOMAIN_ENV, str(domain))
        monkeypatch.delenv(domains.HELD_ENV, raising=False)
        assert cli.main(['cell', '-o', str(tmp_path / 'busy')]) == 2
    finally:
        lock.close()
    err = capsys.readouterr().err
    assert f'cell not started: ROS domain {domain} is used by another run' in err
    assert "(unset: ROS's default 0), never a free one" in err and 'first free' not in err
