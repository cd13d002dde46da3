"""Regroup test files by subject (issue 21): merge whole modules into one, keeping every test function's source
(docstring and assertions) as it is. Imports are unioned and left for ``ruff --fix`` to sort; module-level helpers
travel with their module, and a name defined twice with different sources is an error (rename first).

    python bench/experiments/regroup_tests.py PLAN.json    # {"target.py": ["source.py", ...]}

A source ``file.py::pattern`` takes only the tests whose names match the glob (several joined by ``|``;
``!pattern``: those that do not), with every module-level helper of the file.
"""

from __future__ import annotations

import ast
import fnmatch
import json
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parents[2] / "tests"


def _parts(path: Path):
    text = path.read_text()
    tree = ast.parse(text)
    lines = text.splitlines(keepends=True)
    doc = ast.get_docstring(tree)
    imports, body = [], []
    for node in tree.body:
        start = node.lineno - 1
        if getattr(node, "decorator_list", None):
            start = min(d.lineno for d in node.decorator_list) - 1
        src = "".join(lines[start : node.end_lineno])
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            imports.append(src)
        elif isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and node is tree.body[0]:
            continue  # the module docstring
        else:
            name = getattr(node, "name", None)
            if name is None and isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                name = ",".join(t.id for t in targets if isinstance(t, ast.Name))
            body.append((name, src))
    return doc, imports, body


def regroup(plan: dict) -> None:
    used = set()
    out = {}
    for target, sources in plan.items():
        docs, imports, body, names = [], [], [], {}
        tpath = TESTS / target
        if tpath.exists() and not any(x.partition("::")[0] == target for x in sources):
            sources = [target, *sources]
        for spec in sources:
            fname, _, pattern = spec.partition("::")
            doc, imps, items = _parts(TESTS / fname)
            if pattern:
                neg = pattern.startswith("!")
                pats = pattern.lstrip("!").split("|")
                items = [
                    (n, src)
                    for n, src in items
                    if not (n or "").startswith("test_") or any(fnmatch.fnmatch(n, p) for p in pats) != neg
                ]
                doc = None
            if doc:
                docs.append(doc)
            imports += imps
            for name, src in items:
                if name in names and names[name] != src:
                    raise SystemExit(f"{target}: {name} defined twice ({names[name][:40]!r} ...)")
                if name in names:
                    continue
                names[name] = src
                body.append(src)
            used.add(fname)
        head = '"""' + "\n\n".join(docs).strip() + '"""\n\n' if docs else ""
        out[tpath] = head + "".join(dict.fromkeys(imports)) + "\n\n" + "\n\n".join(b.rstrip() for b in body) + "\n"
        print(f"{target}: {len(body)} items from {len(sources)} sources")
    # Written only once every target has been built: a conflict leaves the tests as they were.
    for tpath, text in out.items():
        tpath.write_text(text)
    for fname in used - set(plan):
        (TESTS / fname).unlink()
        print(f"removed {fname}")


if __name__ == "__main__":
    regroup(json.loads(Path(sys.argv[1]).read_text()))
