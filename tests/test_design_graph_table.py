"""
design.md §1 and §3 and nodes.md show what the nodes record opening (ibvs_bringup.graph_topics).

The records (ibvs_bringup/opened_topics.py) are regenerated here from the nodes themselves,
so that a node opening another topic fails this test until the file, and with it §1's node
table, §3's topic table and tests/test_process_graph.py's expectations, say so.
"""

from pathlib import Path
import re

from ibvs_bringup import graph_topics

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / 'docs' / 'design.md'
#: §3's generated table sits between these lines.
BEGIN, END = '<!-- topics: generated -->', '<!-- topics: end -->'
TOPIC = re.compile(r'`(/[^`]+)`')


def _section(text, number):
    return text.split(f'\n## {number}. ', 1)[1].split(f'\n## {number + 1}. ', 1)[0]


def _section_1_table(text):
    rows = [line for line in _section(text, 1).splitlines() if line.startswith('|')]
    return '\n'.join(rows) + '\n'


def _expand(topic):
    """``/a/{left,right}/b`` -> [/a/left/b, /a/right/b]."""
    m = re.search(r'\{([^}]+)\}', topic)
    if not m:
        return [topic]
    return [x for alt in m.group(1).split(',')
            for x in _expand(topic[:m.start()] + alt + topic[m.end():])]


def test_opened_topics_are_what_the_nodes_record():
    # On a difference: python -m ibvs_bringup.graph_topics --write (from the repository root).
    assert (ROOT / graph_topics.GENERATED).read_text() == \
        graph_topics.render(graph_topics.record())


def test_design_md_shows_the_graph_description():
    # On a difference: paste graph_topics.node_table() into docs/design.md §1.
    assert _section_1_table(DESIGN.read_text()) == graph_topics.node_table()


def test_design_md_section_3_is_generated_and_describes_every_topic():
    section = _section(DESIGN.read_text(), 3)
    generated = section.split(BEGIN, 1)[1].split(END, 1)[0].strip() + '\n'
    # On a difference: paste graph_topics.contract_table() between the markers.
    assert generated == graph_topics.contract_table()
    # The hand-written table (topic | stamp and content) describes each of them, no other.
    prose = section.split(END, 1)[1]
    described = {t for line in prose.splitlines() if line.startswith('| `')
                 for cell in [line.split('|')[1]] for m in TOPIC.findall(cell)
                 for t in _expand(m)}
    opened = {r.topic for mode in graph_topics.MODES for r in graph_topics.endpoints(mode)}
    assert described == opened


def test_node_topics_merge_pairs_and_name_modes():
    rows = [graph_topics.Opened('n', 'subscribes', f'/a/{side}/b', 't', 'RELIABLE', modes)
            for side in ('left', 'right') for modes in [tuple(graph_topics.MODES)]]
    rows.append(graph_topics.Opened('n', 'subscribes', '/c', 't', 'RELIABLE', ('zed',)))
    assert graph_topics.node_topics('n', 'subscribes', rows) == '/a/{left,right}/b; /c (zed)'
    assert graph_topics.node_topics('n', 'publishes', rows) == ''


def test_nodes_md_lists_each_nodes_topics_and_parameters():
    text = (ROOT / 'docs' / 'nodes.md').read_text()
    generated = text.split('<!-- nodes: generated -->\n', 1)[1].split('<!-- nodes: end -->', 1)[0]
    # On a difference: paste graph_topics.node_tables() between the markers.
    assert generated == graph_topics.node_tables()
