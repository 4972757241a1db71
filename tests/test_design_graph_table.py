"""docs/design.md §1's node table is the graph's description (ibvs_bringup.graph)."""

from pathlib import Path

from ibvs_bringup.graph import GRAPH

DESIGN = Path(__file__).resolve().parents[1] / 'docs' / 'design.md'


def _section_1_table(text):
    section = text.split('\n## 1. ', 1)[1].split('\n## 2. ', 1)[0]
    rows = [line for line in section.splitlines() if line.startswith('|')]
    return '\n'.join(rows) + '\n'


def test_design_md_shows_the_graph_description():
    # On a difference: paste GRAPH.markdown_table() into docs/design.md §1.
    assert _section_1_table(DESIGN.read_text()) == GRAPH.markdown_table()
