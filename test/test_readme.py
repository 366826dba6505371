"""The documentation: generated tables match the code, README commands, size and links.

The README is the entry page (at most 15,000 characters); the reference pages are under
``docs/``. Generated blocks (``<!-- tag -->`` ... ``<!-- /...`` markers) live on the page
that documents them: the sensor grades and the simulator's parameters on
``docs/simulator_node.md``, the alignment node's parameters on ``docs/parameters.md`` (the site,
the phases' flow, the installation, the IMU model) and ``docs/parameters_tuning.md`` (the rest,
from :data:`TUNING_FROM` on). No docs page is longer than :data:`PAGE_MAX_BYTES`.
"""
import re
from pathlib import Path

import numpy as np
import pytest

from sins_align_ros.sim.presets import SENSOR_GRADES

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / 'README.md').read_text()
DOCS = ROOT / 'docs'
README_MAX_CHARS = 15000

#: generated block -> the page it lives on
BLOCK_PAGES = {
    'grades': DOCS / 'simulator_node.md',
    'params:simulator_node': DOCS / 'simulator_node.md',
    'params:alignment_node': DOCS / 'parameters.md',
    'params:alignment_node:tuning': DOCS / 'parameters_tuning.md',
}
#: the alignment node's first parameter on docs/parameters_tuning.md
TUNING_FROM = 'zero_velocity_sigma'
#: the longest a docs page may be (issue 47: pages a reader takes in at once)
PAGE_MAX_BYTES = 15000


def _block(tag):
    page = BLOCK_PAGES[tag]
    m = re.search(rf'<!-- {re.escape(tag)} -->\n(.*?)\n<!-- /', page.read_text(), re.S)
    assert m, f'{page.relative_to(ROOT)} has no <!-- {tag} --> block'
    return m.group(1).strip()


def _fmt(x):
    return f'{x:g}'


def grades_table():
    """The sensor-grade table as docs/simulator_node.md shows it."""
    rows = ['| grade | gyro bias (deg/h) | gyro ARW (deg/rt-h) | gyro Markov (deg/h, tau s) '
            '| accel bias (ug) | accel VRW (ug/rt-Hz) | accel Markov (ug, tau s) |',
            '|---|---|---|---|---|---|---|']
    for name, s in SENSOR_GRADES.items():
        gm = (f'{_fmt(s.gyro_markov_dph)}, {_fmt(s.gyro_markov_tau_s)}'
              if s.gyro_markov_dph else '-')
        am = (f'{_fmt(s.accel_markov_ug)}, {_fmt(s.accel_markov_tau_s)}'
              if s.accel_markov_ug else '-')
        rows.append(f'| `{name}` | {_fmt(np.mean(s.gyro_bias_dph))} | {_fmt(s.gyro_arw_dpsh)} '
                    f'| {gm} | {_fmt(np.mean(s.accel_bias_ug))} | {_fmt(s.accel_vrw_ug_rthz)} '
                    f'| {am} |')
    return '\n'.join(rows)


def test_readme_sensor_grade_table_matches_presets():
    assert _block('grades') == grades_table()


@pytest.mark.parametrize('node', ['simulator_node', 'alignment_node'])
def test_readme_parameter_tables_match_declarations(node):
    pytest.importorskip('rclpy')
    from sins_align_ros.ros.params import markdown_table
    if node == 'simulator_node':
        from sins_align_ros.ros.simulator_node import PARAMS
    else:
        from sins_align_ros.ros.alignment_node import PARAMS
    parts = {f'params:{node}': PARAMS}
    if node == 'alignment_node':
        k = [p.name for p in PARAMS].index(TUNING_FROM)
        parts = {f'params:{node}': PARAMS[:k], f'params:{node}:tuning': PARAMS[k:]}
    for tag, params in parts.items():
        page = BLOCK_PAGES[tag].relative_to(ROOT)
        assert _block(tag) == markdown_table(params), (
            f'{page} parameter table <!-- {tag} --> of {node} is stale; paste '
            f'markdown_table of its parameters (test_readme.py says which)')


def test_readme_commands_exist():
    for cmd in ('scripts/demo.sh', 'scripts/test.sh'):
        assert cmd in README and (ROOT / cmd).exists()
    assert 'scripts/test.sh' in (ROOT / '.ci' / 'run').read_text()


def test_readme_is_short():
    """The entry page stays an entry page; the reference lives in docs/."""
    size = len((ROOT / 'README.md').read_bytes())        # what `wc -c` counts
    assert size <= README_MAX_CHARS, (
        f'README.md has {size} characters (limit {README_MAX_CHARS}): move detail to docs/')


@pytest.mark.parametrize('page', sorted(DOCS.glob('*.md')), ids=lambda p: p.name)
def test_docs_pages_are_short(page):
    size = len(page.read_bytes())
    assert size <= PAGE_MAX_BYTES, (
        f'docs/{page.name} has {size} bytes (limit {PAGE_MAX_BYTES}): split it')


def _slug(heading):
    """GitHub's anchor for a Markdown heading."""
    text = re.sub(r'`|\*\*|\*', '', heading.strip().lower())
    text = re.sub(r'\[([^\]]*)\]\([^)]*\)', r'\1', text)
    return re.sub(r'[^\w\- ]', '', text).replace(' ', '-')


def _without_code(text):
    """The text with fenced code blocks and inline code removed (no links in there)."""
    text = re.sub(r'^```.*?^```', '', text, flags=re.S | re.M)
    return re.sub(r'`[^`\n]*`', '', text)


def _anchors(path):
    text = re.sub(r'^```.*?^```', '', path.read_text(), flags=re.S | re.M)
    return {_slug(h) for h in re.findall(r'^#{1,6}\s+(.+?)\s*#*$', text, re.M)}


def _relative_links(path):
    """(target, fragment) of every relative link and image of a Markdown page."""
    for target in re.findall(r'\]\(([^)\s]+)(?:\s+"[^"]*")?\)', _without_code(path.read_text())):
        if re.match(r'[a-z][a-z0-9+.-]*:', target, re.I):            # http:, mailto:, ...
            continue
        file, _, fragment = target.partition('#')
        yield file, fragment


DOC_PAGES = [ROOT / 'README.md'] + sorted(DOCS.glob('*.md'))


def test_docs_pages_exist():
    for name in ('design', 'alignment_node', 'simulator_node', 'replay', 'filters', 'results',
                 'testing'):
        assert (DOCS / f'{name}.md').is_file(), f'docs/{name}.md missing'
        assert f'(docs/{name}.md)' in README, f'README does not link docs/{name}.md'


@pytest.mark.parametrize('page', DOC_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_point_to_existing_files(page):
    broken = []
    for file, fragment in _relative_links(page):
        target = (page.parent / file).resolve() if file else page
        if not target.exists():
            broken.append(f'{file} (no such file)')
        elif fragment and target.suffix == '.md' and fragment not in _anchors(target):
            broken.append(f'{file}#{fragment} (no such heading)')
    assert not broken, f'{page.relative_to(ROOT)}: broken links: {broken}'
