"""Mutation score of the test suite with cosmic-ray, on a reproducible sample of mutants (see README.md here).

    python bench/mutation/mutate.py run NAME --code REV [--tests REV] [--rate 0.01]   # sample, then cosmic-ray exec
    python bench/mutation/mutate.py run NAME --code REV --scope lib --map [--confirm]  # the library, mapped tests
    python bench/mutation/mutate.py rerun NAME NEW --tests REV [--map [--confirm]]      # NAME's survivors, other tests
    python bench/mutation/mutate.py report NAME                                         # summary from the session

Each run works in a throwaway copy, /tmp/warp_lamp_mutation/NAME/code (``git archive``: warp_lamp/, examples/
and pyproject.toml of the code's revision, the rest of the tree of the tests' revision), because cosmic-ray writes
each mutant into the source file before it runs the tests. Warp compiles every mutated kernel module afresh, into
its own cache (/tmp/warp_lamp_mutation/warpcache).

The sample: cosmic-ray's mutants of the scope's files (``SCOPES``: ``all`` is warp_lamp/ and examples/, ``lib`` is
warp_lamp/ less warp_lamp/bench/, cli.py and the functions that draw figures), restricted to the operators in
``OPERATORS`` (the classic set: + <-> -, * <-> /, the comparison boundaries and negations, bit operators swapped,
unary minus and ``not`` removed, numbers +-1, True <-> False, and <-> or, loops run zero times, break <-> continue),
each kept when a hash of (file, operator, the stripped source line, the how-many-th such mutant of that line) falls
below ``rate``. Unchanged lines therefore keep the same mutants from one commit to another, which is what makes two
commits' scores comparable, and a scope's sample is the other scope's sample on the files they share. The tests
run as ``pytest -x`` (stop at the first failure) under ``nice -n 15``: the whole suite, or with ``--map`` first the
test files of the mutated module (``TEST_MAP``) and, with ``--confirm``, the rest of the suite on the mutants that
survive them (``test-mutant``, the per-mutant command).
"""

from __future__ import annotations

import argparse
import ast
import collections
import gzip
import hashlib
import json
import os
import queue
import shutil
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WORK = Path(os.environ.get("WARP_LAMP_MUTATION_DIR", "/tmp/warp_lamp_mutation"))
RESULTS = Path(__file__).resolve().parent / "results"

_PAIRS = [
    ("Add", "Sub"), ("Sub", "Add"), ("Mul", "Div"), ("Div", "Mul"), ("FloorDiv", "Div"), ("Mod", "FloorDiv"),
    ("Pow", "Mul"), ("BitAnd", "BitOr"), ("BitOr", "BitAnd"), ("BitXor", "BitOr"), ("LShift", "RShift"),
    ("RShift", "LShift"),
]  # fmt: skip
_COMPARE = [
    ("Lt", "LtE"), ("LtE", "Lt"), ("Gt", "GtE"), ("GtE", "Gt"), ("Eq", "NotEq"), ("NotEq", "Eq"), ("Is", "IsNot"),
    ("IsNot", "Is"), ("Lt", "GtE"), ("Gt", "LtE"),
]  # fmt: skip
#: cosmic-ray operators in the sample.
OPERATORS = {
    *(f"core/ReplaceBinaryOperator_{a}_{b}" for a, b in _PAIRS),
    *(f"core/ReplaceComparisonOperator_{a}_{b}" for a, b in _COMPARE),
    "core/ReplaceUnaryOperator_Delete_USub",
    "core/ReplaceUnaryOperator_Delete_Not",
    "core/ReplaceUnaryOperator_Delete_Invert",
    "core/NumberReplacer",
    "core/AddNot",
    "core/ReplaceTrueWithFalse",
    "core/ReplaceFalseWithTrue",
    "core/ReplaceAndWithOr",
    "core/ReplaceOrWithAnd",
    "core/ZeroIterationForLoop",
    "core/ReplaceBreakWithContinue",
    "core/ReplaceContinueWithBreak",
}

TEST_COMMAND = "bash -c 'rm -rf .hypothesis && exec python -m pytest -x -q -p no:cacheprovider {tests}'"

#: The files each scope mutates: cosmic-ray's ``module-path`` and ``excluded-modules`` (globs), and whether the
#: functions that draw figures are left out (``_drawing_lines``). ``all`` is the rule of the runs before issue 21;
#: ``lib`` is issue 21's: the library less its benchmark sections, its command line and its plots. Every plot in
#: warp_lamp/ is in warp_lamp/bench/ (``speed.plot``, ``modes.plot_area``, ``porosity.plot_histograms``) and
#: examples/ is outside warp_lamp/, so today the drawing filter removes nothing; it keeps a future plot out.
SCOPES = {
    "all": {"paths": ["warp_lamp", "examples"], "excluded": [], "drawing": False},
    "lib": {"paths": ["warp_lamp"], "excluded": ["warp_lamp/bench/*.py", "warp_lamp/cli.py"], "drawing": True},
}

_LAMP_CORE = [
    "tests/test_lamp.py", "tests/test_errors.py", "tests/test_walls.py", "tests/test_follow.py",
    "tests/test_frames.py", "tests/test_peers.py", "tests/test_device_contract.py",
]  # fmt: skip
_AREA = ["tests/test_area.py"]
_WETTED = ["tests/test_wetted.py"]
_DIST = ["tests/test_distributed.py"]
_ENDS = ["tests/test_cli.py", "tests/test_readme.py"]
_LAMP = [*_LAMP_CORE, *_AREA, *_WETTED, *_DIST, *_ENDS]
_POROSITY = ["tests/test_porosity.py", *_DIST, "tests/test_readme.py"]
_MEASURES = ["tests/test_measures.py", "tests/test_readme.py"]
_BENCH = ["tests/test_bench.py"]
_IO = ["tests/test_cli.py"]
#: With ``--map``, the test files run first on a mutant of each module (an exact path, or a folder ending in "/";
#: the longest match wins; a module in neither runs the whole suite): the files that exercise it, the most direct
#: and quickest first, so that ``-x`` stops early. A mutant that fails any of them fails the whole suite, which
#: contains them: the map can only miss kills, never make one. ``--confirm`` runs the rest of the suite on the
#: mutants that survive their files, so that a survivor is one the whole suite lets live.
TEST_MAP = {
    "warp_lamp/lamp.py": _LAMP,
    "warp_lamp/estimators.py": _LAMP,
    "warp_lamp/pipeline.py": _LAMP,
    "warp_lamp/grid.py": [*_LAMP, *_MEASURES],
    "warp_lamp/frames.py": ["tests/test_frames.py", "tests/test_follow.py", *_LAMP],
    "warp_lamp/validate.py": [*_LAMP, *_POROSITY, *_MEASURES, *_IO],
    "warp_lamp/wetted.py": [*_WETTED, *_LAMP],
    "warp_lamp/porosity.py": _POROSITY,
    "warp_lamp/distributed.py": [*_DIST, *_LAMP_CORE],
    "warp_lamp/bench/peers.py": ["tests/test_peers.py", "tests/test_porosity.py", *_LAMP],
    "warp_lamp/measures.py": [*_MEASURES, *_LAMP, "tests/test_engines.py", "tests/test_tolerance.py"],
    "warp_lamp/scenes.py": ["tests/test_scenes.py", *_LAMP, *_POROSITY, *_MEASURES],
    "warp_lamp/tolerance.py": ["tests/test_tolerance.py", "tests/test_lamp.py", "tests/test_cli.py"],
    "warp_lamp/particles_io.py": _IO,
    "warp_lamp/export.py": _IO,
    "warp_lamp/timing.py": _BENCH,
    "warp_lamp/engines/": ["tests/test_engines.py"],
    "warp_lamp/kernels/": _LAMP,
    "warp_lamp/kernels/footprint.py": [*_LAMP, *_POROSITY],
    "warp_lamp/kernels/area.py": [*_AREA, *_LAMP],
    "warp_lamp/kernels/wetted.py": [*_WETTED, *_LAMP],
    "warp_lamp/kernels/wetted_base.py": [*_WETTED, *_LAMP],
    "warp_lamp/kernels/wetted_sweeps.py": [*_WETTED, *_LAMP],
    "warp_lamp/kernels/wetted_cross.py": [*_WETTED, *_LAMP],
    "warp_lamp/kernels/porosity.py": _POROSITY,
    "warp_lamp/kernels/distributed.py": _DIST,
    "warp_lamp/kernels/peers.py": ["tests/test_peers.py", "tests/test_porosity.py", *_LAMP],
    "warp_lamp/kernels/packing.py": ["tests/test_scenes.py", *_POROSITY],
    "warp_lamp/reference/": _LAMP,
    "warp_lamp/reference/area.py": [*_AREA, *_LAMP],
    "warp_lamp/reference/wetted.py": [*_WETTED, *_LAMP],
    "warp_lamp/reference/porosity.py": _POROSITY,
    "warp_lamp/reference/distributed.py": _DIST,
}
#: With ``--map``, a stage (the mapped files, or the rest of the suite) that runs past its baseline time times this
#: factor plus ``_COMPILE_S`` is stopped and the mutant counted as killed (a timeout, reported as such): the
#: allowance is for recompiling the mutated kernel module and the modules that include its functions.
_TIMEOUT_FACTOR = 3.0
_COMPILE_S = 300.0


def _map_files(module: str, plan: dict, code: Path) -> list[str] | None:
    """The mapped test files of a module that exist in this tree, in order, once each; None: not in the map."""
    folders = [k for k in plan if k.endswith("/") and module.startswith(k)]
    key = module if module in plan else max(folders, default=None, key=len)
    if key is None:
        return None
    return [f for f in dict.fromkeys(plan[key]) if (code / f).exists()]


def _suite_files(code: Path) -> list[str]:
    """The files that ``pytest tests`` collects (tests/ is flat)."""
    return sorted(str(p.relative_to(code)) for p in (code / "tests").glob("test_*.py"))


def _config(code: Path, timeout: float, tests: str = "tests", scope: str = "all", command: str | None = None) -> str:
    paths = ", ".join(f'"{p}"' for p in SCOPES[scope]["paths"])
    excluded = ", ".join(f'"{p}"' for p in SCOPES[scope]["excluded"])
    return (
        "[cosmic-ray]\n"
        f"module-path = [{paths}]\n"
        f"timeout = {timeout}\n"
        f"excluded-modules = [{excluded}]\n"
        f'test-command = "{command or TEST_COMMAND.format(tests=tests)}"\n'
        "[cosmic-ray.distributor]\n"
        'name = "local"\n'
    )


def _env(code: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(code)
    env["WARP_CACHE_PATH"] = str(WORK / "warpcache")
    # The specimen cache too: a mutant must not write a packing where the user's tests would read it. The
    # baseline fills it with the unmutated packings, which every mutant then reads: mutants of the packing code
    # are masked by it (README.md here).
    env["WARP_LAMP_CACHE"] = str(code.parent / "scenes")
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


def _checkout(rev: str, dest: Path, paths: list[str]) -> str:
    """``git archive`` of ``paths`` at ``rev`` into dest; returns the full commit id."""
    commit = subprocess.check_output(["git", "-C", str(ROOT), "rev-parse", rev], text=True).strip()
    dest.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit, *paths], check=True, capture_output=True)
    subprocess.run(["tar", "x", "-C", str(dest)], input=archive.stdout, check=True)
    return commit


#: The library and its examples: the code that a run mutates. Everything else in the tree (tests/, and the README,
#: bench/ and docs/ that the tests read) comes from the tests' revision.
CODE = ["warp_lamp", "examples", "pyproject.toml"]


def _tree(code_rev: str, tests_rev: str, dest: Path) -> tuple[str, str]:
    """The tests' revision's tree with ``CODE`` from the code's revision, into dest; returns both commit ids."""
    tests = _checkout(tests_rev, dest, ["."])
    for path in CODE:
        target = dest / path
        if target.is_dir():
            shutil.rmtree(target)
        else:
            target.unlink(missing_ok=True)
    return _checkout(code_rev, dest, CODE), tests


def _drawing_lines(path: Path) -> set[int]:
    """The lines of the functions that draw figures (those that import matplotlib), with their nested code."""
    lines: set[int] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for sub in ast.walk(node):
            names = [a.name for a in sub.names] if isinstance(sub, ast.Import) else []
            if isinstance(sub, ast.ImportFrom):
                names = [sub.module or ""]
            if any(n.split(".")[0] == "matplotlib" for n in names):
                lines.update(range(node.lineno, node.end_lineno + 1))
                break
    return lines


def _position(item) -> tuple:
    """A work item's place in the source: (file, start, occurrence), the order the sample and its parts use."""
    m = item.mutations[0]
    return str(m.module_path), m.start_pos, m.occurrence


def _sample_keys(session: Path, code: Path, drawing: bool = False) -> tuple[dict[str, float], int]:
    """Each mutant's place in [0, 1) (job id -> hash fraction) for the operator set's mutants: a hash of (file,
    operator, stripped source line, how many such mutants of that line came before it). With ``drawing``, the
    mutants inside the functions that draw figures are left out (after the count, so that the others keep their
    keys); returns the keys and how many were left out."""
    from cosmic_ray.work_db import WorkDB, use_db

    lines: dict[Path, list[str]] = {}
    draws: dict[Path, set[int]] = {}
    seen: collections.Counter = collections.Counter()
    keys = {}
    dropped = 0
    with use_db(str(session), WorkDB.Mode.open) as db:
        items = sorted(db.work_items, key=_position)
        for item in items:
            m = item.mutations[0]
            path = code / m.module_path
            if path not in lines:
                lines[path] = path.read_text().splitlines()
                draws[path] = _drawing_lines(path) if drawing else set()
            text = lines[path][m.start_pos[0] - 1].strip()
            base = f"{m.module_path}|{m.operator_name}|{text}"
            key = f"{base}|{seen[base]}"
            seen[base] += 1
            if m.operator_name in OPERATORS:
                if m.start_pos[0] in draws[path]:
                    dropped += 1
                    continue
                keys[item.job_id] = int(hashlib.sha1(key.encode()).hexdigest()[:12], 16) / 16**12
    return keys, dropped


def _sample(session: Path, code: Path, rate: float, drawing: bool = False) -> tuple[int, int, int]:
    """Mark every mutant outside the sample as skipped; returns (in the sample, in the operator set, left out as
    drawing code)."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    keys, dropped = _sample_keys(session, code, drawing)
    (session.parent / "keys.json").write_text(json.dumps(keys))
    with use_db(str(session), WorkDB.Mode.open) as db:
        skip = [item.job_id for item in db.pending_work_items if keys.get(item.job_id, 1.0) >= rate]
        db.set_multiple_results(skip, WorkResult(output="not in the sample", worker_outcome=WorkerOutcome.SKIPPED))
    return sum(k < rate for k in keys.values()), len(keys), dropped


def _part(session: Path, part: str) -> int:
    """Keep one part of a sample (``K/N``: every N-th mutant in (module, position) order from the K-th, so that each
    part has its share of every module), marking the others skipped, so that N runs on N cores each run a part of
    one sample; ``merge`` joins their results. Returns the mutants kept."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    k, n = (int(x) for x in part.split("/"))
    with use_db(str(session), WorkDB.Mode.open) as db:
        pending = sorted(db.pending_work_items, key=_position)
        other = [w.job_id for i, w in enumerate(pending) if i % n != k]
        db.set_multiple_results(
            other, WorkResult(output=f"in another part than {part}", worker_outcome=WorkerOutcome.SKIPPED)
        )
    return len(pending) - len(other)


def _forget(session: Path, jobs: list[str]) -> None:
    """Delete these jobs' results, so that ``cosmic-ray exec`` runs them (again)."""
    with sqlite3.connect(session) as con:
        con.executemany("DELETE FROM work_results WHERE job_id = ?", [(j,) for j in jobs])


def _resample(run: Path, rate: float) -> int:
    """Move a session to another rate: mutants below it and not yet run become pending, the others not yet run are
    skipped; results already measured stay. Returns the mutants now in the sample."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    keys = json.loads((run / "keys.json").read_text())
    with use_db(str(run / "session.sqlite"), WorkDB.Mode.open) as db:
        results = dict(db.results)
        # Only the sample's own skips move: another part's mutants and exported ones stay where they are.
        skipped = {
            j
            for j, r in results.items()
            if r.worker_outcome == WorkerOutcome.SKIPPED and r.output == "not in the sample"
        }
    _forget(run / "session.sqlite", [j for j in skipped if keys.get(j, 1.0) < rate])
    with use_db(str(run / "session.sqlite"), WorkDB.Mode.open) as db:
        sleep = [item.job_id for item in db.pending_work_items if keys.get(item.job_id, 1.0) >= rate]
        db.set_multiple_results(sleep, WorkResult(output="not in the sample", worker_outcome=WorkerOutcome.SKIPPED))
    meta = json.loads((run / "meta.json").read_text())
    meta["rate"] = rate
    (run / "meta.json").write_text(json.dumps(meta))
    return sum(k < rate for k in keys.values())


def _baseline(code: Path, tests: str = "tests") -> float:
    t0 = time.perf_counter()
    proc = subprocess.run(
        ["nice", "-n", "15", "bash", "-c", TEST_COMMAND.format(tests=tests).split("'")[1]],
        cwd=code,
        env=_env(code),
        check=False,
    )
    if proc.returncode != 0:
        sys.exit(f"baseline: the unmutated suite fails in {code}; fix that first")
    return time.perf_counter() - t0


def _pending_modules(session: Path) -> set[str]:
    from cosmic_ray.work_db import WorkDB, use_db

    with use_db(str(session), WorkDB.Mode.open) as db:
        return {str(item.mutations[0].module_path) for item in db.pending_work_items}


def _prepare_map(run: Path, code: Path, session: Path, confirm: bool) -> None:
    """Time each distinct set of mapped files that the pending mutants will run, on the unmutated code and alone
    (a set that fails alone would kill every mutant of its modules: refuse), and the whole suite when the survivors
    are to be confirmed; write the per-stage timeouts and the per-mutant command into the session."""
    meta = json.loads((run / "meta.json").read_text())
    stages: dict[str, float] = {}
    if confirm:
        stages["suite"] = _baseline(code)
        print(f"{run.name}: baseline, whole suite {stages['suite']:.0f} s", flush=True)
    sets = {tuple(f) for m in _pending_modules(session) if (f := _map_files(m, TEST_MAP, code)) is not None}
    for files in sorted(sets):
        stages[" ".join(files)] = _baseline(code, " ".join(files))
        print(f"{run.name}: baseline {stages[' '.join(files)]:5.0f} s  {' '.join(files)}", flush=True)
    if any(_map_files(m, TEST_MAP, code) is None for m in _pending_modules(session)) and "suite" not in stages:
        stages["suite"] = _baseline(code)
    meta.update(map=TEST_MAP, confirm=confirm, baseline_s=stages)
    (run / "meta.json").write_text(json.dumps(meta))
    shutil.copy(Path(__file__), run / "mutate.py")
    longest = max(stages.values()) if stages else 0.0
    backstop = 2 * (_TIMEOUT_FACTOR * longest + _COMPILE_S) + 600
    command = f"{sys.executable} {run / 'mutate.py'} test-mutant {run}"
    scope = meta.get("scope", "all")
    (run / "cr.toml").write_text(_config(code, backstop, scope=scope, command=command))


def cmd_run(args) -> None:
    run = WORK / args.name
    code = run / "code"
    session = run / "session.sqlite"
    if not session.exists():
        if code.exists():
            shutil.rmtree(code)
        commit, tests = _tree(args.code, args.tests or args.code, code)
        (run / "cr.toml").write_text(_config(code, args.timeout, scope=args.scope))
        (run / "meta.json").write_text(
            json.dumps({"code": commit, "tests": tests, "rate": args.rate, "scope": args.scope, "part": args.part})
        )
        subprocess.run(["cosmic-ray", "init", str(run / "cr.toml"), str(session)], cwd=code, check=True)
        kept, allowed, dropped = _sample(session, code, args.rate, SCOPES[args.scope]["drawing"])
        print(f"{args.name}: {kept} mutants sampled of {allowed} in the operator set and scope", flush=True)
        if args.part:
            print(f"{args.name}: part {args.part}: {_part(session, args.part)} of them here", flush=True)
        if dropped:
            print(f"{args.name}: {dropped} mutants of functions that draw figures left out", flush=True)
        if args.map:
            _prepare_map(run, code, session, args.confirm)
        else:
            print(f"{args.name}: baseline suite {_baseline(code):.0f} s", flush=True)
    else:
        print(f"{args.name}: {_resample(run, args.rate)} mutants in the sample at rate {args.rate}", flush=True)
    _exec(run, code, session)
    cmd_report(args)


def _exec(run: Path, code: Path, session: Path) -> None:
    # A run stopped mid-mutant leaves that mutant written into the copy: put the archived source back first.
    git = ["git", "-c", "user.name=mutation", "-c", "user.email=mutation@localhost"]
    if not (code / ".git").exists():
        subprocess.run([*git, "init", "-q"], cwd=code, check=True)
        subprocess.run([*git, "add", "-A", "warp_lamp", "examples", "tests"], cwd=code, check=True)
        subprocess.run([*git, "commit", "-q", "-m", "archived source"], cwd=code, check=True)
    subprocess.run([*git, "checkout", "-q", "--", "."], cwd=code, check=True)
    t0 = time.perf_counter()
    subprocess.run(
        ["nice", "-n", "15", "cosmic-ray", "exec", str(run / "cr.toml"), str(session)],
        cwd=code,
        env=_env(code),
        check=True,
    )
    print(f"exec: {time.perf_counter() - t0:.0f} s", flush=True)


def _stage(files: list[str], timeout: float) -> tuple[str, float, str]:
    """``pytest -x`` on these files in the copy (the current directory): ("passed" | "failed" | "timeout", seconds,
    output)."""
    shutil.rmtree(".hypothesis", ignore_errors=True)
    t0 = time.perf_counter()
    # A group of its own, so that a timeout stops the processes the tests start (MPI ranks, the CLI).
    proc = subprocess.Popen(
        [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *files],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate()
        return "timeout", time.perf_counter() - t0, out
    return ("passed" if proc.returncode == 0 else "failed"), time.perf_counter() - t0, out


def cmd_test_mutant(args) -> None:
    """The per-mutant test command of a ``--map`` session, run by cosmic-ray in the copy with the mutant written in:
    the mutated module's mapped files, then (``confirm``) the rest of the suite. Its last line says which stage
    decided (``report`` reads it); exit status 0: survived."""
    run = Path(args.run)
    meta = json.loads((run / "meta.json").read_text())
    code = Path.cwd()
    # ``remote`` names the mutated module (its trees are plain copies, not git work trees).
    changed = (
        os.environ.get("MUTATE_CHANGED", "").split()
        or subprocess.run(
            ["git", "diff", "--name-only", "--", "warp_lamp", "examples"], capture_output=True, text=True, check=True
        ).stdout.split()
    )
    suite = _suite_files(code)
    files = _map_files(changed[0], meta["map"], code) if len(changed) == 1 else None
    plan = [("map", files), ("rest", [f for f in suite if f not in files])] if files else [("suite", suite)]
    if files and not meta["confirm"]:
        plan = plan[:1]
    spent = []
    for stage, stage_files in plan:
        if not stage_files:
            continue
        base = meta["baseline_s"].get("suite" if stage != "map" else " ".join(stage_files))
        if base is None:  # the rest of a suite whose baseline was not run: bound it by the whole suite's
            base = meta["baseline_s"].get("suite", 600.0)
        limit = _TIMEOUT_FACTOR * base + _COMPILE_S
        # ``remote``'s hard end: a stage cut there is no verdict (exit 3), and the mutant goes back to the queue.
        end = float(os.environ.get("MUTATE_HARD_END", "inf"))
        verdict, seconds, out = _stage(stage_files, min(limit, end - time.time()))
        if verdict == "timeout" and time.time() >= end - 1:
            print("mutate.py: cut at remote's hard end")
            sys.exit(3)
        spent.append(f"{stage} {seconds:.0f} s")
        if verdict != "passed":
            failed = [x for x in out.splitlines() if x.startswith(("FAILED ", "ERROR "))]
            print("\n".join(out.splitlines()[-40:]))
            what = f"timeout after {limit:.0f} s" if verdict == "timeout" else f"killed by {stage}"
            first = f": {failed[0].split(' - ')[0]}" if failed else ""
            print(f"mutate.py: {what} ({', '.join(spent)}){first}")
            sys.exit(1)
    print(f"mutate.py: survived {' + '.join(s for s, f in plan if f)} ({', '.join(spent)})")


def cmd_rerun(args) -> None:
    """Run another test tree on the survivors of a finished run (its killed mutants stay killed)."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome

    old = WORK / args.name
    run = WORK / args.new
    code = run / "code"
    session = run / "session.sqlite"
    if not session.exists():
        meta = json.loads((old / "meta.json").read_text())
        if code.exists():
            shutil.rmtree(code)
        commit, tests = _tree(meta["code"], args.tests, code)
        select = " ".join(args.select) if args.select else "tests"
        scope = meta.get("scope", "all")
        (run / "cr.toml").write_text(_config(code, args.timeout, select, scope=scope))
        (run / "meta.json").write_text(
            json.dumps(
                {
                    "code": commit,
                    "tests": tests,
                    "rate": meta["rate"],
                    "scope": scope,
                    "rerun_of": args.name,
                    "select": None if args.map else select,
                }
            )
        )
        shutil.copy(old / "session.sqlite", session)
        shutil.copy(old / "keys.json", run / "keys.json")
        with use_db(str(session), WorkDB.Mode.open) as db:
            survivors = [job for job, res in db.results if res.test_outcome == TestOutcome.SURVIVED]
        _forget(session, survivors)
        print(f"{args.new}: {len(survivors)} survivors of {args.name} to run again", flush=True)
        if args.map:
            _prepare_map(run, code, session, args.confirm)
        else:
            print(f"{args.new}: baseline suite {_baseline(code, select):.0f} s", flush=True)
    _exec(run, code, session)
    args.name = args.new
    cmd_report(args)


def _decided_by(output: str) -> tuple[str, str]:
    """(stage, first failing test) from a ``test-mutant`` output's last line; ("", "") for whole-suite runs."""
    last = output.strip().splitlines()[-1] if output.strip() else ""
    if not last.startswith("mutate.py: "):
        return "", ""
    head, _, test = last.partition("): ")
    if last.startswith("mutate.py: survived"):
        return ("confirmed" if "rest" in head or "suite" in head else "map only"), ""
    if "timeout" in head:
        return "timeout", ""
    return head.split("killed by ")[1].split(" ")[0], test.removeprefix("FAILED ").removeprefix("ERROR ")


def _tally(rows: list[dict], *, staged: bool) -> dict:
    """The score of result rows (``report``'s, or several parts' joined): killed counts timeouts and incompetent
    mutants; with ``staged`` (a ``--map`` run), which stage decided them."""
    done = [r for r in rows if r["outcome"] != "pending"]
    killed = [r for r in done if r["outcome"] in ("killed", "timeout", "incompetent")]
    out = {
        "sampled": len(rows),
        "done": len(done),
        "killed": len(killed),
        "timeouts": sum(r["outcome"] == "timeout" for r in done),
        "survived": len(done) - len(killed),
        "score": len(killed) / len(done) if done else None,
    }
    if staged:
        stages = collections.Counter(r.get("stage", "earlier run") for r in done)
        out["decided_by"] = dict(sorted(stages.items()))
        # A survivor of its mapped files alone may still fail the rest: the score is then a lower bound.
        out["score_is"] = "exact" if not stages.get("map only") else "a lower bound (survivors not confirmed)"
    return out


def cmd_report(args) -> None:
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome

    run = WORK / args.name
    meta = json.loads((run / "meta.json").read_text())
    keys = json.loads((run / "keys.json").read_text())
    below = getattr(args, "below", None)
    rows = []
    with use_db(str(run / "session.sqlite"), WorkDB.Mode.open) as db:
        results = dict(db.results)
        for item in db.work_items:
            res = results.get(item.job_id)
            if res is not None and res.worker_outcome == WorkerOutcome.SKIPPED:
                continue
            m = item.mutations[0]
            if below is not None and keys[item.job_id] >= below:
                continue
            outcome = "pending" if res is None else str(res.test_outcome.value if res.test_outcome else "none")
            stage, test = _decided_by(res.output or "") if res is not None else ("", "")
            if res is not None and (res.output == "timeout" or stage == "timeout"):
                outcome = "timeout"
            tail = (res.output or "").strip().splitlines()[-1:] if res is not None else []
            row = {
                "job": item.job_id,
                "module": str(m.module_path),
                "line": m.start_pos[0],
                "operator": m.operator_name,
                "key": round(keys[item.job_id], 6),
                "outcome": outcome,
                "diff": "\n".join(
                    x for x in (res.diff or "").splitlines() if x[:1] in "+-" and x[:3] not in ("---", "+++")
                )
                if res is not None
                else "",
                "last_line": tail[0] if tail else "",
            }
            if stage:
                row.update(stage=stage, killed_by=test)
            rows.append(row)
    rows.sort(key=lambda r: (r["module"], r["line"], r["operator"]))
    summary = {
        **{k: v for k, v in meta.items() if k != "map"},
        "map": "map" in meta,
        "sample": f"key < {below if below is not None else meta['rate']}",
        **_tally(rows, staged="map" in meta),
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    name = args.name if below is None else f"{args.name}-below-{below}"
    (RESULTS / f"{name}.json").write_text(json.dumps({"summary": summary, "mutants": rows}, indent=1) + "\n")
    print(json.dumps(summary, indent=1))
    for r in rows:
        if r["outcome"] == "survived":
            diff = r["diff"].replace("\n", "\n    ")
            print(f"survived {r['module']}:{r['line']} {r['operator']} {r.get('stage', '')}\n    {diff}")


def cmd_merge(args) -> None:
    """Join the results of the parts of one sample (``run --part``) into results/NAME.json."""
    parts = [json.loads((RESULTS / f"{p}.json").read_text()) for p in args.parts]
    heads = [
        {k: v for k, v in p["summary"].items() if k in ("code", "tests", "rate", "scope", "confirm")} for p in parts
    ]
    if any(h != heads[0] for h in heads):
        sys.exit(f"merge: the parts differ in {heads}")
    rows = sorted((r for p in parts for r in p["mutants"]), key=lambda r: (r["module"], r["line"], r["operator"]))
    summary = {
        **heads[0],
        "parts": args.parts,
        "baseline_s": [p["summary"].get("baseline_s") for p in parts],
        "sample": f"key < {heads[0]['rate']}",
        **_tally(rows, staged=True),
    }
    (RESULTS / f"{args.name}.json").write_text(json.dumps({"summary": summary, "mutants": rows}, indent=1) + "\n")
    print(json.dumps(summary, indent=1))


def cmd_export(args) -> None:
    """Write the pending mutants of a ``--map`` session as mutated module texts for ``remote`` on a machine with more
    cores, and mark them skipped here ("exported"), so that this machine's run goes on with the rest (the modules
    in ``--keep``: those whose tests need extras the other machine lacks). ``import`` brings the verdicts back."""
    import cosmic_ray.plugins
    from cosmic_ray.mutating import mutate_code
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    run = WORK / args.name
    meta = json.loads((run / "meta.json").read_text())
    if "baseline_s" not in meta:
        sys.exit(f"export: {args.name} has no baselines yet (its run has not reached exec)")
    sources: dict[str, str] = {}
    jobs = []
    with use_db(str(run / "session.sqlite"), WorkDB.Mode.open) as db:
        for item in db.pending_work_items:
            m = item.mutations[0]
            module = str(m.module_path)
            if any(module.startswith(k) for k in args.keep):
                continue
            if module not in sources:
                sources[module] = subprocess.run(
                    ["git", "show", f"{meta['code']}:{module}"], cwd=ROOT, capture_output=True, text=True, check=True
                ).stdout
            operator = cosmic_ray.plugins.get_operator(m.operator_name)(**(getattr(m, "operator_args", None) or {}))
            text = mutate_code(sources[module], operator, m.occurrence)
            if text is not None:
                jobs.append({"job": item.job_id, "module": module, "text": text})
        db.set_multiple_results(
            [j["job"] for j in jobs], WorkResult(output="exported", worker_outcome=WorkerOutcome.SKIPPED)
        )
    out = Path(args.out)
    with gzip.open(out, "wt") as f:
        json.dump({"name": args.name, "meta": meta, "sources": sources, "jobs": jobs}, f)
    print(f"export: {len(jobs)} mutants of {args.name} to {out}")


def cmd_remote(args) -> None:
    """Run exported mutants on this machine, ``--workers`` at a time, each in its own copy of the tree (CPU only, as
    on the recipe's machine), through the same ``test-mutant`` stages and limits; each verdict is appended to
    ``--out`` as it comes (JSON lines), and no mutant starts after ``--deadline`` seconds."""
    data = json.load(gzip.open(args.jobs, "rt"))
    work = Path(args.work)
    rundir = work / "run"
    rundir.mkdir(parents=True, exist_ok=True)
    (rundir / "meta.json").write_text(json.dumps(data["meta"]))
    shutil.copy(Path(__file__), rundir / "mutate.py")
    skip = shutil.ignore_patterns(
        ".git", ".w*", ".mut", ".before", ".scenes", "__pycache__", ".hypothesis", "*.egg-info"
    )
    scenes = ROOT / ".scenes"
    t0 = time.time()
    jobs: queue.Queue = queue.Queue()
    if args.baseline:
        # The unmutated code on each distinct set of mapped files first: a set that fails here would kill mutants
        # for this machine's sake, not theirs.
        sets = {}
        for j in data["jobs"]:
            files = _map_files(j["module"], data["meta"]["map"], ROOT)
            sets.setdefault(tuple(files or ()), j["module"])
        for module in sets.values():
            jobs.put({"job": f"baseline:{module}", "module": module, "text": data["sources"][module]})
    for j in data["jobs"]:
        jobs.put(j)
    lock = threading.Lock()
    out = Path(args.out)

    def worker(i: int) -> None:
        tree = work / f"tree{i}"
        if not tree.exists():
            shutil.copytree(ROOT, tree, ignore=skip)
            if scenes.exists():
                shutil.copytree(scenes, work / f"scenes{i}")
        env = dict(os.environ)
        env.update(
            PYTHONPATH=f"{tree}:{env.get('PYTHONPATH', '')}",
            WARP_CACHE_PATH=str(work / "warpcache"),
            WARP_LAMP_CACHE=str(work / f"scenes{i}"),
            PYTHONDONTWRITEBYTECODE="1",
            CUDA_VISIBLE_DEVICES="",
            # Lent machines run as root, which OpenMPI's mpiexec refuses unless told (MPICH does not ask).
            OMPI_ALLOW_RUN_AS_ROOT="1",
            OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
        )
        while time.time() - t0 < args.deadline:
            try:
                j = jobs.get_nowait()
            except queue.Empty:
                return
            path = tree / j["module"]
            path.write_text(j["text"])
            s0 = time.perf_counter()
            proc = subprocess.run(
                [sys.executable, str(rundir / "mutate.py"), "test-mutant", str(rundir)],
                cwd=tree,
                env={**env, "MUTATE_CHANGED": j["module"], "MUTATE_HARD_END": str(t0 + args.hard_end)},
                capture_output=True,
                text=True,
                check=False,
            )
            path.write_text(data["sources"][j["module"]])
            if proc.returncode == 3:
                continue
            row = {"job": j["job"], "rc": proc.returncode, "seconds": round(time.perf_counter() - s0, 1)}
            row["output"] = "\n".join((proc.stdout + proc.stderr).splitlines()[-45:])
            with lock, out.open("a") as f:
                f.write(json.dumps(row) + "\n")

    threads = [threading.Thread(target=worker, args=(i,)) for i in range(args.workers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print(f"remote: {sum(1 for _ in out.open())} verdicts in {time.time() - t0:.0f} s; {jobs.qsize()} not started")


def cmd_import(args) -> None:
    """Record ``remote``'s verdicts in the session (exit status 0: survived), and make the exported mutants without
    one pending again."""
    import difflib

    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome, WorkResult

    run = WORK / args.name
    data = json.load(gzip.open(args.jobs, "rt"))
    rows = {}
    for path in args.results:
        for line in Path(path).read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                rows[r["job"]] = r
    with use_db(str(run / "session.sqlite"), WorkDB.Mode.open) as db:
        for j in data["jobs"]:
            r = rows.get(j["job"])
            if r is None:
                continue
            diff = difflib.unified_diff(
                data["sources"][j["module"]].splitlines(), j["text"].splitlines(), j["module"], j["module"], lineterm=""
            )
            db.set_multiple_results(
                [j["job"]],
                WorkResult(
                    worker_outcome=WorkerOutcome.NORMAL,
                    output=r["output"],
                    test_outcome=TestOutcome.SURVIVED if r["rc"] == 0 else TestOutcome.KILLED,
                    diff="\n".join(diff),
                ),
            )
    missing = [j["job"] for j in data["jobs"] if j["job"] not in rows]
    _forget(run / "session.sqlite", missing)
    print(f"import: {len(data['jobs']) - len(missing)} verdicts into {args.name}; {len(missing)} pending again")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="sample the mutants of a commit and run its tests (or another commit's) on them")
    run.add_argument("name")
    run.add_argument("--code", required=True, help="git revision whose warp_lamp/ and examples/ are mutated")
    run.add_argument("--tests", help="git revision whose tests/ run (default: --code)")
    run.add_argument("--rate", type=float, default=0.01, help="fraction of the operator set's mutants sampled")
    run.add_argument("--scope", choices=sorted(SCOPES), default="all", help="the files mutated (SCOPES)")
    run.add_argument("--timeout", type=float, default=300.0, help="seconds per mutant; past it, killed (timeout)")
    run.add_argument("--part", help="K/N: run only the K-th of N interleaved parts of the sample (see merge)")
    rerun = sub.add_parser("rerun", help="run another revision's tests on the survivors of a finished run")
    rerun.add_argument("name")
    rerun.add_argument("new")
    rerun.add_argument("--tests", required=True)
    rerun.add_argument(
        "--select",
        nargs="*",
        help="test paths to run (default: tests): the tests that differ from the first run's, since its survivors "
        "passed all the others",
    )
    rerun.add_argument("--timeout", type=float, default=300.0)
    for p in (run, rerun):
        p.add_argument("--map", action="store_true", help="run the mutated module's test files first (TEST_MAP)")
        p.add_argument(
            "--confirm", action="store_true", help="with --map: run the rest of the suite on the survivors of the map"
        )
    report = sub.add_parser("report", help="write results/NAME.json from a session and list the survivors")
    report.add_argument("name")
    report.add_argument("--below", type=float, help="only the mutants whose sample key is below this (a subsample)")
    merge = sub.add_parser("merge", help="join the results of a sample's parts (run --part K/N) into results/NAME.json")
    merge.add_argument("name")
    merge.add_argument("parts", nargs="+", help="the parts' result names")
    export = sub.add_parser("export", help="the pending mutants of a session, for remote on another machine")
    export.add_argument("name")
    export.add_argument("out", help="a .json.gz to write")
    export.add_argument("--keep", nargs="*", default=[], help="module prefixes left to this machine's run")
    remote = sub.add_parser("remote", help="run exported mutants here, several at a time")
    remote.add_argument("jobs")
    remote.add_argument("--out", required=True, help="JSON lines of verdicts, appended")
    remote.add_argument("--work", default="/tmp/mutation_remote")
    remote.add_argument("--baseline", action="store_true", help="first run each mapped set on the unmutated code")
    remote.add_argument("--workers", type=int, default=max(1, (os.cpu_count() or 2) - 2))
    remote.add_argument("--deadline", type=float, default=420.0, help="seconds after which no mutant starts")
    remote.add_argument("--hard-end", type=float, default=540.0, help="seconds after which a running mutant is cut")
    imp = sub.add_parser("import", help="record remote's verdicts in the session")
    imp.add_argument("name")
    imp.add_argument("jobs")
    imp.add_argument("results", nargs="+")
    test = sub.add_parser("test-mutant", help="(cosmic-ray's per-mutant command in a --map session)")
    test.add_argument("run")
    args = parser.parse_args(argv)
    if getattr(args, "confirm", False) and not args.map:
        parser.error("--confirm needs --map")
    {
        "run": cmd_run,
        "rerun": cmd_rerun,
        "report": cmd_report,
        "merge": cmd_merge,
        "export": cmd_export,
        "remote": cmd_remote,
        "import": cmd_import,
        "test-mutant": cmd_test_mutant,
    }[args.command](args)


if __name__ == "__main__":
    main()
