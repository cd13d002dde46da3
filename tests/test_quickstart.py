"""The README's quick start is examples/quickstart.py, and it runs as written."""

import re
import runpy
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def quickstart_code() -> str:
    """examples/quickstart.py without its module docstring."""
    text = (ROOT / "examples" / "quickstart.py").read_text()
    return text[text.index('"""', 3) + 3 :].lstrip("\n")


def test_readme_quick_start_is_the_example_verbatim():
    """The README's "Quick start" code block is examples/quickstart.py, line for line."""
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## Quick start") :]
    block = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert block == quickstart_code()


def test_quickstart_runs_and_its_forces_balance(capsys):
    """The quick start runs on the CPU as written: forces sum to zero, porosity is physical, float32 forces are
    within rounding of the exact ones, and nothing is skipped."""
    runpy.run_path(str(ROOT / "examples" / "quickstart.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "sum of forces [0.0, 0.0, 0.0] N" in out
    centre, corner = (float(x) for x in re.search(r"centre cell ([\d.]+), corner cell ([\d.]+)", out).groups())
    assert 0.2 < centre < 0.6 and corner > centre
    assert float(re.search(r"float32 forces within (\S+) N", out).group(1)) < 1e-5
    assert "resultant [0.0, 0.0, 0.0] N; skipped: invalid 0, outside the grid 0" in out


def test_citation_and_changelog_name_the_sources_and_this_version():
    """CITATION.cff asks for the memo and the paper beside the library, at the package's version, and the
    changelog has an entry for that version."""
    import yaml

    import warp_lamp

    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["version"] == warp_lamp.__version__
    titles = " ".join(ref["title"] for ref in cff["references"])
    assert "shining-lamp" in titles and "Porosity Calculation Algorithm" in titles
    assert f"## {warp_lamp.__version__}" in (ROOT / "CHANGELOG.md").read_text()
