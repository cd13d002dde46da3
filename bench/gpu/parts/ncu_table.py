"""Print the rows of an Nsight Compute ``--csv --page details`` report whose metric names contain any of the given
words (all rows without any): ``python3 bench/gpu/parts/ncu_table.py report.csv [word ...]``."""

import csv
import sys


def main() -> None:
    path, keep = sys.argv[1], sys.argv[2:]
    try:
        with open(path) as f:
            rows = list(csv.DictReader(line for line in f if line.startswith('"')))
    except Exception as e:  # a report that ncu did not write is said, not raised: the lease goes on
        print("no csv:", e)
        return
    for r in rows:
        name = r.get("Metric Name", "")
        if not keep or any(k in name for k in keep):
            where = r.get("Kernel Name", "")[:28] if "Kernel Name" in r else r.get("Section Name", "")[:22]
            print(f"  {where:28s} {name[:64]:64s} {r.get('Metric Value', '')} {r.get('Metric Unit', '')}")


if __name__ == "__main__":
    main()
