"""Mutation score of the test suite with cosmic-ray, on a reproducible sample of mutants (see README.md here).

    python bench/mutation/mutate.py run NAME --code REV [--tests REV] [--rate 0.01]   # sample, then cosmic-ray exec
    python bench/mutation/mutate.py rerun NAME NEW --tests REV                          # NAME's survivors, other tests
    python bench/mutation/mutate.py report NAME                                         # summary from the session

Each run works in a throwaway copy, /tmp/warp_lamp_mutation/NAME/code (``git archive`` of REV: warp_lamp/,
examples/, tests/, pyproject.toml), because cosmic-ray writes each mutant into the source file before it runs the
tests. Warp compiles every mutated kernel module afresh, into its own cache (/tmp/warp_lamp_mutation/warpcache).

The sample: cosmic-ray's mutants of warp_lamp/ and examples/, restricted to the operators in ``OPERATORS`` (the
classic set: + <-> -, * <-> /, the comparison boundaries and negations, bit operators swapped, unary minus and
``not`` removed, numbers +-1, True <-> False, and <-> or, loops run zero times, break <-> continue), each kept when
a hash of (file, operator, the stripped source line, the how-many-th such mutant of that line) falls below
``rate``. Unchanged lines therefore keep the same mutants from one commit to another, which is what makes two
commits' scores comparable. The tests run as ``pytest -x`` (stop at the first failure) under ``nice -n 15``.
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import json
import os
import shutil
import sqlite3
import subprocess
import sys
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


def _config(code: Path, timeout: float, tests: str = "tests") -> str:
    return (
        "[cosmic-ray]\n"
        'module-path = ["warp_lamp", "examples"]\n'
        f"timeout = {timeout}\n"
        "excluded-modules = []\n"
        f'test-command = "{TEST_COMMAND.format(tests=tests)}"\n'
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


def _sample_keys(session: Path, code: Path) -> dict[str, float]:
    """Each mutant's place in [0, 1) (job id -> hash fraction) for the operator set's mutants: a hash of (file,
    operator, stripped source line, how many such mutants of that line came before it)."""
    from cosmic_ray.work_db import WorkDB, use_db

    lines: dict[Path, list[str]] = {}
    seen: collections.Counter = collections.Counter()
    keys = {}
    with use_db(str(session), WorkDB.Mode.open) as db:
        items = sorted(
            db.work_items,
            key=lambda w: (str(w.mutations[0].module_path), w.mutations[0].start_pos, w.mutations[0].occurrence),
        )
        for item in items:
            m = item.mutations[0]
            path = code / m.module_path
            if path not in lines:
                lines[path] = path.read_text().splitlines()
            text = lines[path][m.start_pos[0] - 1].strip()
            base = f"{m.module_path}|{m.operator_name}|{text}"
            key = f"{base}|{seen[base]}"
            seen[base] += 1
            if m.operator_name in OPERATORS:
                keys[item.job_id] = int(hashlib.sha1(key.encode()).hexdigest()[:12], 16) / 16**12
    return keys


def _sample(session: Path, code: Path, rate: float) -> tuple[int, int]:
    """Mark every mutant outside the sample as skipped; returns (in the sample, in the operator set)."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    keys = _sample_keys(session, code)
    (session.parent / "keys.json").write_text(json.dumps(keys))
    with use_db(str(session), WorkDB.Mode.open) as db:
        skip = [item.job_id for item in db.pending_work_items if keys.get(item.job_id, 1.0) >= rate]
        db.set_multiple_results(skip, WorkResult(output="not in the sample", worker_outcome=WorkerOutcome.SKIPPED))
    return sum(k < rate for k in keys.values()), len(keys)


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
        skipped = {j for j, r in results.items() if r.worker_outcome == WorkerOutcome.SKIPPED}
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


def cmd_run(args) -> None:
    run = WORK / args.name
    code = run / "code"
    session = run / "session.sqlite"
    if not session.exists():
        if code.exists():
            shutil.rmtree(code)
        commit = _checkout(args.code, code, ["warp_lamp", "examples", "pyproject.toml"])
        tests = _checkout(args.tests or args.code, code, ["tests"])
        (run / "cr.toml").write_text(_config(code, args.timeout))
        (run / "meta.json").write_text(json.dumps({"code": commit, "tests": tests, "rate": args.rate}))
        subprocess.run(["cosmic-ray", "init", str(run / "cr.toml"), str(session)], cwd=code, check=True)
        kept, allowed = _sample(session, code, args.rate)
        print(f"{args.name}: {kept} mutants sampled of {allowed} in the operator set", flush=True)
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
        commit = _checkout(meta["code"], code, ["warp_lamp", "examples", "pyproject.toml"])
        tests = _checkout(args.tests, code, ["tests"])
        select = " ".join(args.select) if args.select else "tests"
        (run / "cr.toml").write_text(_config(code, args.timeout, select))
        (run / "meta.json").write_text(
            json.dumps({"code": commit, "tests": tests, "rate": meta["rate"], "rerun_of": args.name, "select": select})
        )
        shutil.copy(old / "session.sqlite", session)
        shutil.copy(old / "keys.json", run / "keys.json")
        with use_db(str(session), WorkDB.Mode.open) as db:
            survivors = [job for job, res in db.results if res.test_outcome == TestOutcome.SURVIVED]
        _forget(session, survivors)
        print(f"{args.new}: {len(survivors)} survivors of {args.name} to run again", flush=True)
        print(f"{args.new}: baseline suite {_baseline(code, select):.0f} s", flush=True)
    _exec(run, code, session)
    args.name = args.new
    cmd_report(args)


def cmd_report(args) -> None:
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome

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
            if res is not None and res.output == "timeout":
                outcome = "timeout"
            tail = (res.output or "").strip().splitlines()[-1:] if res is not None else []
            rows.append(
                {
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
            )
    rows.sort(key=lambda r: (r["module"], r["line"], r["operator"]))
    done = [r for r in rows if r["outcome"] not in ("pending",)]
    killed = [r for r in done if r["outcome"] in (TestOutcome.KILLED.value, "timeout", TestOutcome.INCOMPETENT.value)]
    summary = {
        **meta,
        "sample": f"key < {below if below is not None else meta['rate']}",
        "sampled": len(rows),
        "done": len(done),
        "killed": len(killed),
        "timeouts": sum(r["outcome"] == "timeout" for r in done),
        "survived": len(done) - len(killed),
        "score": len(killed) / len(done) if done else None,
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    name = args.name if below is None else f"{args.name}-below-{below}"
    (RESULTS / f"{name}.json").write_text(json.dumps({"summary": summary, "mutants": rows}, indent=1) + "\n")
    print(json.dumps(summary, indent=1))
    for r in rows:
        if r["outcome"] == "survived":
            diff = r["diff"].replace("\n", "\n    ")
            print(f"survived {r['module']}:{r['line']} {r['operator']}\n    {diff}")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="sample the mutants of a commit and run its tests (or another commit's) on them")
    run.add_argument("name")
    run.add_argument("--code", required=True, help="git revision whose warp_lamp/ and examples/ are mutated")
    run.add_argument("--tests", help="git revision whose tests/ run (default: --code)")
    run.add_argument("--rate", type=float, default=0.01, help="fraction of the operator set's mutants sampled")
    run.add_argument("--timeout", type=float, default=300.0, help="seconds per mutant; past it, killed (timeout)")
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
    report = sub.add_parser("report", help="write results/NAME.json from a session and list the survivors")
    report.add_argument("name")
    report.add_argument("--below", type=float, help="only the mutants whose sample key is below this (a subsample)")
    args = parser.parse_args(argv)
    {"run": cmd_run, "rerun": cmd_rerun, "report": cmd_report}[args.command](args)


if __name__ == "__main__":
    main()
