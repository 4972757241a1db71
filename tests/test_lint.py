"""Lint the cross-package tests as ament does for the packages (flake8 and pep257)."""

from pathlib import Path

from ament_flake8.main import main_with_errors
from ament_pep257.main import main as pep257_main
import pytest

HERE = Path(__file__).resolve().parent
#: The cross-package tests, their conftest, and the repository's helper scripts.
PATHS = [str(HERE), str(HERE.parent / 'conftest.py'), str(HERE.parent / 'tools')]


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8():
    rc, errors = main_with_errors(argv=PATHS)
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    assert pep257_main(argv=PATHS) == 0
