"""Every Python block of README.md and of the documentation's pages (docs/getting-started.md, docs/guide/*.md)
runs as written, each on its own (a reader copies one block, not the page), in a fresh namespace, and ends with an
assert of its result (a block that runs but computes nonsense fails); a block that cannot run alone says so with
``<!-- fragment: why -->`` on the line before it, and still compiles.

The measured figures of the README and the pages that any machine can recompute (the CPU ones; GPU timings live
in result files): each is asserted to its printed precision, so that a change that moves one fails here instead of
silently making the text wrong. bench/mutation/README_CLAIMS.md lists every figure and where its evidence is."""

import ast
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from warp_lamp.bench.porosity import table_1
from warp_lamp.measures import lone_sphere_error
from warp_lamp.reference import PAPER_TABLE_1, midpoint_sphere_offsets

ROOT = Path(__file__).resolve().parents[1]

FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


#: Where a reader copies code from: the README and the site's pages (their blocks were the README's).
SOURCES = [
    "README.md",
    "docs/getting-started.md",
    *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("guide/*.md")),
]


def readme_blocks() -> list[tuple[str, str, str | None]]:
    """("file:line", code, fragment reason or None) for each ```python block of the README and the site's pages."""
    out = []
    for source in SOURCES:
        text = (ROOT / source).read_text()
        for m in FENCE.finditer(text):
            before = text[: m.start()].rstrip("\n").rsplit("\n", 1)[-1]
            mark = re.fullmatch(r"<!-- fragment: (.+?) -->", before.strip())
            where = f"{source}:{text[: m.start()].count(chr(10)) + 1}"
            out.append((where, m.group(1), mark.group(1) if mark else None))
    return out


BLOCKS = readme_blocks()


def test_the_readme_has_python_blocks_and_every_fragment_says_why():
    """The blocks are found (the fence pattern is not stale) and a fragment mark gives its reason."""
    assert sum(b[0].startswith("README.md:") for b in BLOCKS) >= 1  # the quick start
    assert sum(b[0].startswith("docs/") for b in BLOCKS) >= 5
    for line, code, why in BLOCKS:
        compile(code, line, "exec")  # fragments too: at least they parse
        assert why is None or len(why) > 10, line


def test_every_runnable_block_ends_by_checking_its_result():
    """Each block that runs ends with an assert (of what it computed), so that its exit status means something."""
    for line, code, why in BLOCKS:
        if why is None:
            last = ast.parse(code).body[-1]
            assert isinstance(last, ast.Assert), f"{line}: the block does not end with an assert"


@pytest.mark.parametrize(("line", "code", "why"), BLOCKS, ids=[b[0] for b in BLOCKS])
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
        exec(compile(code, line, "exec"), namespace)


ACCURACY = {1: ["21.9", "7.9", "2.5", "0.95"], 0: ["161", "72", "34", "16"]}


def agrees(value: float, printed: str) -> bool:
    """value rounds to the printed figure (half a unit of its last digit)."""
    decimals = len(printed.split(".")[1]) if "." in printed else 0
    return abs(value - float(printed)) <= 0.5 * 10.0**-decimals + 1e-12


def test_agrees_reads_the_printed_precision():
    """The helper itself: 21.94 is 21.9 and 21.96 is not; 161.4 is 161 and 161.6 is not."""
    assert agrees(21.94, "21.9") and not agrees(21.96, "21.9")
    assert agrees(161.4, "161") and not agrees(161.6, "161")


@pytest.mark.parametrize("criterion", [1, 0])
def test_lone_sphere_accuracy_table(device, criterion):
    """README "Accuracy": E_area over 256 offsets is 21.9 / 7.9 / 2.5 / 0.95 % (criterion 1) and 161 / 72 / 34 /
    16 % (criterion 0) at 2, 4, 8 and 16 cells per diameter."""
    for k, printed in zip((2, 4, 8, 16), ACCURACY[criterion], strict=True):
        e = 100 * lone_sphere_error(criterion, k, device, samples=256)
        assert agrees(e, printed), (criterion, k, e, printed)


def test_paper_table_1_figures():
    """The porosity page's "Paper's Table 1": with the line ends included the counts would be 4,873 (r = 10) and 68,075
    (r = 25); the paper's counts are 0.3% under the ball's volume at r = 10, 2.2% under at 25 and 17% under at 4,
    but 4.4% over at r = 2 and 1.0% over at r = 5."""
    assert len(midpoint_sphere_offsets(10, line_ends=True)) == 4873
    assert len(midpoint_sphere_offsets(25, line_ends=True)) == 68075
    fill = {r: 100 * (PAPER_TABLE_1[r - 1] / (4 / 3 * np.pi * r**3) - 1) for r in (2, 4, 5, 10, 25)}
    for r, printed in ((10, "-0.3"), (25, "-2.2"), (4, "-17"), (2, "4.4"), (5, "1.0")):
        assert agrees(fill[r], printed), (r, fill[r])


def test_voxel_column_of_table_1():
    """Table 1's voxel column (porosity page; the bench's sub-cell-centre count, 64 offsets): RMS 4,190.3 and error
    0.23% at r = 10, 65,450.8 and 0.04% at r = 25, 30.9% at r = 1; the midpoint column equals the paper's."""
    rows = {t["r"]: t for t in table_1()}
    assert [rows[r]["midpoint"] for r in range(1, 26)] == PAPER_TABLE_1
    for r, rms, err in ((10, "4190.3", "0.23"), (25, "65450.8", "0.04"), (1, "4.4", "30.9"), (5, "523.2", "0.98")):
        assert agrees(rows[r]["voxel_rms"], rms), (r, rows[r])
        assert agrees(100 * rows[r]["voxel_rms_error"], err), (r, rows[r])


def test_yade_recipe_makes_its_venv_from_debians_python():
    """Every YADE recipe (the engines page, the example, the adapter) makes the venv with /usr/bin/python3:
    /usr/bin/yade runs Debian's Python, and a python3 first on PATH (pyenv, conda) would not load YADE."""
    for name in ("docs/guide/engines.md", "examples/yade_sphere_test.py", "warp_lamp/engines/yade.py"):
        text = (ROOT / name).read_text()
        venvs = re.findall(r"(\S+) -m venv --system-site-packages ~/yade-env", text)
        assert venvs and set(venvs) == {"/usr/bin/python3"}, (name, venvs)
