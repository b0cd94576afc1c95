"""The documentation links only to files inside the repository, and they exist."""
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
DOCS = sorted([ROOT / 'README.md', *(ROOT / 'docs').glob('*.md'),
               *(ROOT / 'src').glob('*/README.md'),
               ROOT / 'ros_ws' / 'README.md'])
LINK = re.compile(r'\]\(([^)#\s]+)(?:#[^)]*)?\)')


@pytest.mark.parametrize('doc', DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_links_stay_inside_the_repository_and_exist(doc):
    text = doc.read_text()
    assert '../shared' not in text, f'{doc}: points outside the repository'
    for target in LINK.findall(text):
        if re.match(r'[a-z]+://', target):
            continue
        path = (doc.parent / target).resolve()
        assert path.is_relative_to(ROOT), f'{doc}: {target} leaves the repository'
        assert path.exists(), f'{doc}: {target} does not exist'


def test_the_readme_links_the_design_and_shows_the_tools():
    text = (ROOT / 'README.md').read_text()
    assert '(docs/DESIGN.md)' in text and '(docs/BUILD.md)' in text
    for needle in ('scripts/run', 'scripts/test', 'scripts/bench', 'catheter_topic list',
                   'catheter_topic hz', 'catheter_topic info', '--set link.delay=0.5', '--dds',
                   'recover_bag'):
        assert needle in text, needle
