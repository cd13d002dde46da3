"""The documentation site builds with warnings as errors, its pages and API reference are there, and nothing a
user reads names a tracker issue.

The build needs the ``docs`` extra (Sphinx, MyST-parser, furo; also in the ``test`` extra, so CI builds it); it is
skipped where Sphinx is absent. It fetches nothing from the network and runs no notebook."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ISSUE = re.compile(r"\bissues? #?\d+", re.I)
PAGES = ["index", "getting-started", "api", "results", "development"] + [
    f"guide/{p}" for p in ("pressure", "walls", "accurate", "porosity", "simulator", "engines", "gpus", "rock-cutting")
]


def user_text() -> dict[str, str]:
    """README.md and every Markdown page of the site, by path."""
    paths = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    return {str(p.relative_to(ROOT)): p.read_text() for p in paths if "_build" not in p.parts}


def test_no_issue_numbers_in_readme_or_site_sources():
    """README.md and docs/**/*.md name no tracker issue ("issue 19"); the pattern itself catches one."""
    assert ISSUE.search("before issue 19 the fluid") and ISSUE.search("Issues 10 and 19")
    found = {path: ISSUE.findall(text) for path, text in user_text().items()}
    assert not {path: hits for path, hits in found.items() if hits}


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    pytest.importorskip("furo")
    out = tmp_path_factory.mktemp("html")
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(ROOT / "docs"), str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-4000:]
    return out


def test_site_builds_with_warnings_as_errors(site):
    """sphinx-build -W succeeds (the fixture asserts it) and writes every page of the table of contents."""
    for page in PAGES:
        assert (site / f"{page}.html").is_file(), page


def test_api_reference_comes_from_the_docstrings(site):
    """The API page documents the public functions and classes, with their docstrings' text, and every figure
    the pages show is copied into the site."""
    api = (site / "api.html").read_text()
    for name in ("warp_lamp.lamp.lamp_forces", "warp_lamp.lamp.ShiningLamp", "warp_lamp.porosity.porosity",
                 "warp_lamp.distributed.DistributedLamp", "warp_lamp.engines.LammpsLamp"):  # fmt: skip
        assert f'id="{name}"' in api, name
    assert "Fluid pressure" in api  # a parameter's description, so napoleon read the Args sections
    images = {p.name for p in (site / "_images").glob("*.png")}
    assert {"owner_map.png", "bench_lamp.png", "wetted_slice.png", "porosity_histograms.png"} <= images


def test_rendered_site_names_no_issue(site):
    """No page of the built site, the API reference's docstrings included, names a tracker issue."""
    for page in PAGES:
        text = re.sub(r"<[^>]+>", " ", (site / f"{page}.html").read_text())
        assert not ISSUE.findall(text), (page, ISSUE.findall(text))
