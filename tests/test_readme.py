"""Every Python block of README.md runs as written, each on its own (a reader copies one block, not the page), in
a fresh namespace; a block that cannot run alone says so with ``<!-- fragment: why -->`` on the line before it,
and still compiles."""

import re
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def readme_blocks() -> list[tuple[int, str, str | None]]:
    """(line, code, fragment reason or None) for each ```python block of the README."""
    text = (ROOT / "README.md").read_text()
    out = []
    for m in FENCE.finditer(text):
        before = text[: m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        mark = re.fullmatch(r"<!-- fragment: (.+?) -->", before.strip())
        out.append((text[: m.start()].count("\n") + 1, m.group(1), mark.group(1) if mark else None))
    return out


BLOCKS = readme_blocks()


def test_the_readme_has_python_blocks_and_every_fragment_says_why():
    """The blocks are found (the fence pattern is not stale) and a fragment mark gives its reason."""
    assert len(BLOCKS) >= 5
    for line, code, why in BLOCKS:
        compile(code, f"README.md:{line}", "exec")  # fragments too: at least they parse
        assert why is None or len(why) > 10, line


@pytest.mark.parametrize(("line", "code", "why"), BLOCKS, ids=[f"line{b[0]}" for b in BLOCKS])
def test_readme_block_runs_on_its_own(line, code, why, capsys):
    """The block runs in a fresh namespace, with no name it does not define or import, and warns nothing."""
    if why is not None:
        pytest.skip(f"fragment: {why}")
    for module in re.findall(r"^import (\w+)", code, re.M):
        if module not in ("numpy", "warp", "warp_lamp"):
            pytest.importorskip(module)
    namespace = {"__name__": "__readme__"}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        exec(compile(code, f"README.md:{line}", "exec"), namespace)
