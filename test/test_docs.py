"""The user guide: the README stays short, its links and those of docs/ lead somewhere, the verdict's threshold is
quoted right, and no development history is left in the README, the docs or the package's comments."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from plane_validation.core.verdict import RELIABLE_PS

ROOT = Path(__file__).resolve().parents[1]
GUIDES = [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]
#: The README is a user guide; reference material belongs in docs/.
README_MAX_LINES = 300

LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s]+)\)')
HEADING = re.compile(r'^(#{1,6})\s+(.*?)\s*$')
ANCHOR = re.compile(r'<a id="([^"]+)"')
#: Development history: which session, who found it, where the developers keep their data.
HISTORY = re.compile(r'\b(?:first|second|third|fourth|fifth|sixth|seventh|eighth|ninth|tenth|eleventh|twelfth|'
                     r'\w+teenth|twentieth|\w+-\w+(?:st|nd|rd|th)) session\b|\boutside (?:probe|review)\b|'
                     r'shared/data\b', re.I)


def slug(heading: str) -> str:
    """GitHub's anchor for a Markdown heading: lower case, punctuation dropped, spaces as hyphens."""
    text = re.sub(r'[^\w\- ]', '', heading.replace('`', '').strip().lower())
    return text.replace(' ', '-')


def anchors(path: Path) -> set[str]:
    found, seen, fenced = set(), {}, False
    for line in path.read_text('utf8').splitlines():
        if line.startswith('```'):
            fenced = not fenced
            continue
        match = HEADING.match(line)
        if match and not fenced:
            base = slug(match.group(2))
            count = seen.get(base, 0)
            seen[base] = count + 1
            found.add(base if count == 0 else f'{base}-{count}')
        found.update(ANCHOR.findall(line))
    return found


def test_slug_follows_github():
    assert slug('Depth cameras: `noise_model: depth_quadratic`') == 'depth-cameras-noise_model-depth_quadratic'
    assert slug("The paper's figures, reproduced") == 'the-papers-figures-reproduced'
    assert slug('Depth camera or lidar: a cheat sheet') == 'depth-camera-or-lidar-a-cheat-sheet'


def test_readme_is_a_short_guide():
    lines = (ROOT / 'README.md').read_text('utf8').splitlines()
    assert len(lines) <= README_MAX_LINES, f'README.md has {len(lines)} lines: move reference material to docs/'


@pytest.mark.parametrize('guide', GUIDES, ids=lambda p: p.name)
def test_every_relative_link_resolves(guide):
    broken = []
    for target in LINK.findall(guide.read_text('utf8')):
        if re.match(r'[a-z]+:', target):  # https:, mailto:
            continue
        path, _, anchor = target.partition('#')
        dest = (guide.parent / path).resolve() if path else guide
        if not dest.exists():
            broken.append(f'{target}: no such file')
        elif anchor and dest.suffix == '.md' and anchor not in anchors(dest):
            broken.append(f'{target}: no such heading')
    assert not broken, broken


def test_the_guides_quote_the_verdict_threshold():
    for name in ('README.md', 'docs/tuning-and-verdict.md'):
        text = (ROOT / name).read_text('utf8')
        assert f'PS ≥ {RELIABLE_PS}' in text, name
        assert re.search(r'PS ≥ (?!' + re.escape(str(RELIABLE_PS)) + r'\b)\d', text) is None, name


def test_no_development_history_in_the_guides_or_the_code():
    files = GUIDES + sorted((ROOT / 'plane_validation').rglob('*.py')) + sorted((ROOT / 'config').glob('*')) \
        + sorted((ROOT / 'launch').glob('*'))
    found = [f'{path.relative_to(ROOT)}:{number}: {line.strip()}'
             for path in files if path.is_file()
             for number, line in enumerate(path.read_text('utf8').splitlines(), 1) if HISTORY.search(line)]
    assert not found, found


def test_the_history_pattern_finds_history():
    for text in ('(benchmarks/README.md, seventeenth session)', 'an outside probe found it', 'an Outside Review',
                 '../shared/data/office1.pcd', 'the twenty-first session'):
        assert HISTORY.search(text), text
    for text in ('LiveSession', 'the local noise probe', 'start_new_session=True', 'a reviewed value'):
        assert not HISTORY.search(text), text
