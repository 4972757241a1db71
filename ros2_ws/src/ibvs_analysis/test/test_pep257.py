"""Check docstrings as ament_pep257 does."""

from pathlib import Path

from ament_pep257.main import main
import pytest


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    rc = main(argv=[str(Path(__file__).resolve().parents[1])])
    assert rc == 0, 'Found code style errors / warnings'
