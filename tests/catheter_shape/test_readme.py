"""Every ```python snippet of the package README runs as written (issue 11: the README's
`sensor.process(frame)` raised ValueError for a new user)."""
import pytest

from tests.catheter_shape.readme_snippets import python_blocks

BLOCKS = python_blocks('src/catheter_shape/README.md')


def test_the_readme_has_snippets():
    assert len(BLOCKS) >= 3


@pytest.mark.parametrize('line,code', BLOCKS, ids=[f'line{b[0]}' for b in BLOCKS])
def test_readme_snippet_runs(line, code):
    exec(compile(code, f'README.md:{line}', 'exec'), {'__name__': '__readme__'})
