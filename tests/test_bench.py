"""The benchmark CLI runs its quick subset and reports what it measured."""

import json
import subprocess
import sys


def test_bench_quick_runs_and_writes_json(tmp_path):
    """`warp-lamp bench --quick --json` runs on the CPU, prints the tables and writes consistent JSON."""
    out = tmp_path / "bench.json"
    proc = subprocess.run(
        [sys.executable, "-m", "warp_lamp", "bench", "--quick", "--device", "cpu", "--json", str(out), "--no-progress"],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "atomic_min" in proc.stdout and "E_area" in proc.stdout
    result = json.loads(out.read_text())
    assert result["devices"]["cpu"]["copy_GBps"] > 0
    speed = result["speed"][0]
    assert speed["n"] > 1000 and speed["eager_s"] > 0 and speed["bvh_cast_s"] > 0 and speed["reference_s"] > 0
    errors = {(e["criterion"], e["cells_per_diameter"]): e for e in result["errors"]}
    assert errors[(1, 16)]["E_area"] < errors[(1, 2)]["E_area"]
    assert all(e["force_sum"] == [0.0, 0.0, 0.0] for e in result["errors"])
    assert 0.7 < errors[(1, 4)]["mean_pressure_over_P"] < 1.0


def test_bench_porosity_quick_with_paper(tmp_path):
    """`warp-lamp bench porosity --quick --paper` measures every method against exact and reproduces Table 1."""
    out = tmp_path / "porosity.json"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "warp_lamp",
            "bench",
            "porosity",
            "--quick",
            "--paper",
            "--device",
            "cpu",
            "--json",
            str(out),
            "--no-progress",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    saved = json.loads(out.read_text())
    rows = saved["bench"]["rows"]
    assert {r["method"] for r in rows} == {"centroid", "polyhedron", "exact", "voxel", "midpoint"}
    voxel = [r["rms"] for r in rows if r["method"] == "voxel"]
    assert voxel == sorted(voxel, reverse=True)
    assert [t["midpoint"] for t in saved["paper"]["table_1"]] == [t["paper"] for t in saved["paper"]["table_1"]]
    polyhedron = saved["paper"]["cases"][0]["methods"]["polyhedron"]
    assert polyhedron["at_most_0"] > 0.25 and saved["paper"]["cases"][0]["methods"]["voxel"]["at_most_0"] == 0
