"""
The README stays a front page, and the documentation's relative links lead somewhere.

README.md at most 200 lines, the rest in docs/ pages, each reached from the README by links
(directly or through another page); a link to a page that was renamed or never written, or
a page no link leads to, is caught here, not by a reader.
"""

from pathlib import Path
import re

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
README_MAX_LINES = 200
#: Markdown links and images: ``[text](target)`` and ``![alt](target)``; the target ends at
#: the first space (an optional title follows) or closing parenthesis.
LINK = re.compile(r'!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
#: Fenced code blocks, whose brackets are code, not links.
FENCE = re.compile(r'^(```|~~~).*?^\1', re.MULTILINE | re.DOTALL)
INLINE_CODE = re.compile(r'`[^`\n]*`')
HEADING = re.compile(r'^#{1,6}\s+(.+?)\s*#*$', re.MULTILINE)


def pages():
    """Return the README and every docs/*.md page."""
    return [README, *sorted((ROOT / 'docs').glob('*.md'))]


def relative_links(text):
    """
    Return the relative link targets of a Markdown text, without their anchors.

    Parameters
    ----------
    text : str
        Markdown source.

    Returns
    -------
    list of (str, str)
        Each link or image target that is not a URL (no scheme, not mailto), split into the
        path (empty for a link within the page) and the anchor (empty if none).

    """
    text = INLINE_CODE.sub('', FENCE.sub('', text))
    targets = []
    for target in LINK.findall(text):
        if re.match(r'^[a-zA-Z][a-zA-Z0-9+.-]*:', target):
            continue
        path, _, anchor = target.partition('#')
        targets.append((path, anchor))
    return targets


def anchors(page):
    """Return the anchors GitHub gives the headings of a Markdown page."""
    text = FENCE.sub('', page.read_text(encoding='utf-8'))
    return {re.sub(r'[^\w\- ]', '', h.strip().lower()).replace(' ', '-')
            for h in HEADING.findall(text)}


def broken_links(page):
    """Return the relative links of ``page`` whose file, or heading in a .md file, is missing."""
    broken = []
    for path, anchor in relative_links(page.read_text(encoding='utf-8')):
        target = page.parent / path if path else page
        if not target.exists():
            broken.append(path)
        elif anchor and target.suffix == '.md' and anchor not in anchors(target):
            broken.append(f'{path}#{anchor}')
    return broken


def test_readme_is_a_front_page():
    lines = README.read_text(encoding='utf-8').splitlines()
    assert len(lines) <= README_MAX_LINES, (
        f'README.md has {len(lines)} lines, at most {README_MAX_LINES}: move the detail '
        'into a docs/ page and link it')


@pytest.mark.parametrize('page', pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_point_at_files(page):
    assert broken_links(page) == []


def reachable(start):
    """
    Return the Markdown pages that ``start`` links to, directly or through pages it reaches.

    Parameters
    ----------
    start : Path
        The first page (the README).

    Returns
    -------
    set of Path
        Resolved paths of ``start`` and of every existing .md page reached by relative links.

    """
    seen, todo = set(), [start.resolve()]
    while todo:
        page = todo.pop()
        if page in seen or page.suffix != '.md' or not page.is_file():
            continue
        seen.add(page)
        todo += [(page.parent / path).resolve()
                 for path, _ in relative_links(page.read_text(encoding='utf-8')) if path]
    return seen


def test_every_docs_page_is_reachable_from_the_readme():
    reached = reachable(README)
    orphans = [p.name for p in sorted((ROOT / 'docs').glob('*.md')) if p.resolve() not in reached]
    assert orphans == [], (f'docs pages no link leads to from README.md: {orphans}; link each '
                           'from the README or from a page it reaches')


def test_the_reach_follows_links_through_pages(tmp_path):
    (tmp_path / 'README.md').write_text('[a](docs/a.md#top) and [web](https://example.org)\n')
    docs = tmp_path / 'docs'
    docs.mkdir()
    (docs / 'a.md').write_text('# Top\n\n[b](b.md), [gone](gone.md), `[c](c.md)`\n')
    (docs / 'b.md').write_text('[back](../README.md), [a](a.md)\n')
    (docs / 'c.md').write_text('[a](a.md)\n')
    assert reachable(tmp_path / 'README.md') == {
        (tmp_path / 'README.md').resolve(), (docs / 'a.md').resolve(), (docs / 'b.md').resolve()}


def test_the_link_check_finds_a_broken_link(tmp_path):
    page = tmp_path / 'page.md'
    page.write_text('# Top: of it\n\nSee [a](missing.md#x), [b](https://example.org), '
                    '[c](#top-of-it), [c2](#bottom), [g](other.md#where-we-stand), '
                    '[h](other.md#nowhere), ![d](img.png), `[e](code.md)` and\n'
                    '```\n[f](fenced.md)\n```\n')
    (tmp_path / 'img.png').write_bytes(b'')
    (tmp_path / 'other.md').write_text('## Where we stand\n')
    assert broken_links(page) == ['missing.md', '#bottom', 'other.md#nowhere']
