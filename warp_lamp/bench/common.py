"""What every benchmark module shares: the lattice scenes' grid and Markdown tables."""

from __future__ import annotations

from warp_lamp.grid import LampGrid
from warp_lamp.scenes import Scene

__all__ = ["MISSING", "lattice_grid", "markdown_table"]

#: What a table prints where a device or a peer has no value.
MISSING = "\u2013"


def lattice_grid(scene: Scene, cell: float) -> LampGrid:
    """The benchmark's box grid around a lattice scene: the spheres' bounding box plus one cell, cells of ``cell``."""
    lo = scene.centers.min(axis=0) - scene.radii.max() - cell
    hi = scene.centers.max(axis=0) + scene.radii.max() + cell
    return LampGrid(lo, hi, cell)


def markdown_table(header: list[str], rows: list[list[str]]) -> list[str]:
    """Lines of a Markdown table; every row must have one cell per header column."""
    for row in rows:
        if len(row) != len(header):
            raise ValueError(f"table row has {len(row)} cells for {len(header)} columns: {row}")
    return ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)] + [
        "| " + " | ".join(r) + " |" for r in rows
    ]
