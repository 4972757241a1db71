"""
The documentation is a reference: every page reached, every link resolved, no history.

Every docs/*.md page is linked from README.md or from a page the README reaches, and every
relative link of the README and the pages leads to an existing file (anchors are checked by
tests/test_docs.py). Outside docs/CHANGELOG.md no page carries history: no tracker number
(a tracker number) and no date ("2026-11-27"); what changed, and when, is the changelog's.
Citations of upstream sources by commit are references and stay.
"""

import importlib.util
from pathlib import Path
import re

import pytest

#: The link parsing of tests/test_docs.py, one definition of a Markdown link.
_SPEC = importlib.util.spec_from_file_location(
    'docs_link_rules', Path(__file__).resolve().with_name('test_docs.py'))
_DOCS = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(_DOCS)
README, ROOT, pages, reachable, relative_links = (
    _DOCS.README, _DOCS.ROOT, _DOCS.pages, _DOCS.reachable, _DOCS.relative_links)

CHANGELOG = ROOT / 'docs' / 'CHANGELOG.md'
#: A tracker number as history: the word, a space and a number (plural or capitalised). An
#: upstream tracker's "#1946" is a reference, not matched.
ISSUE = re.compile(r'\b[Ii]ssues? \d+')
#: A calendar date.
DATE = re.compile(r'\b20\d\d-[01]\d-[0-3]\d\b')


def test_every_docs_page_is_linked_from_the_readme_or_a_page_it_reaches():
    reached = reachable(README)
    orphans = [p.name for p in sorted((ROOT / 'docs').glob('*.md')) if p.resolve() not in reached]
    assert orphans == []


@pytest.mark.parametrize('page', pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves_to_a_file(page):
    missing = [path for path, _ in relative_links(page.read_text(encoding='utf-8'))
               if path and not (page.parent / path).exists()]
    assert missing == []


def history(text):
    """Return the tracker numbers and dates a Markdown text carries, in order."""
    found = sorted([*ISSUE.finditer(text), *DATE.finditer(text)], key=lambda m: m.start())
    return [m.group(0) for m in found]


@pytest.mark.parametrize('page', [p for p in pages() if p != CHANGELOG],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_no_page_but_the_changelog_carries_history(page):
    assert history(page.read_text(encoding='utf-8')) == [], (
        f'{page.name}: say what is; move what changed, and when, to docs/CHANGELOG.md')


def test_the_history_check_finds_issues_and_dates():
    word = 'issue'  # the examples built here, so that this file names no tracker number
    text = (f'Retuned ({word} 35) on 2026-11-27; {word.title()} 38, item 2; '
            f"ViSP's {word} #1946 and "
            'zed-ros2-wrapper at 33dfefa are references; 2026 frames, 11-27 px.')
    assert history(text) == [f'{word} 35', '2026-11-27', f'{word.title()} 38']
