"""Extract the ```python code blocks of a README (for the tests that run them)."""
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[2]


def python_blocks(readme: str):
    """[(first line number, code)] of every ```python block of ROOT / readme."""
    text = (ROOT / readme).read_text()
    out = []
    for m in re.finditer(r'^```python\n(.*?)^```', text, flags=re.S | re.M):
        out.append((text[:m.start()].count('\n') + 1, m.group(1)))
    return out
