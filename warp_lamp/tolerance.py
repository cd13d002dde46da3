"""Ask for accuracy, not settings: ``tolerance=`` picks the cheapest estimator and cells per diameter.

The choice reads a speed-error table that ``warp-lamp bench tolerance`` measures and the package ships
(``warp_lamp/data/speed_error.json``): for every candidate setting (criterion 1 at 2 to 64 cells per diameter, the
area criterion with its resolvers at 2 to 4), its per-particle force error on the table's scenes and its update
time on each device kind measured.

The rule (:func:`choose_settings`):

1. the error of a setting is the largest, over the table's scenes (a dense random packing and two lattice balls,
   ``warp_lamp.bench.tolerance.table_scenes``), of the RMS per-particle force error against the exact visible
   areas, over the surface particles, relative to P pi rbar^2 (``measures.visible_area_error``);
2. the settings whose error times :data:`MARGIN` (1.2) is at most ``tolerance`` are eligible: a packing the table
   never saw has its own error, and on five lattice balls of other seeds (25 setting-scene pairs) the largest
   ratio of their error to the table's was 1.10;
3. among them, the one with the smallest update time on this device's kind (its time relative to criterion 1 at 4
   cells per diameter on the same kind, so kinds measured on different days compare); a CUDA device of a kind the
   table lacks uses the table's CUDA kind, the CPU the CPU's.

What it does not promise: the error is the table scenes' (dense random packings and a lattice ball of 1.66
radius ratio, the surface particles of a convex body); a body with much finer features than its mean particle,
strongly overlapping spheres or extreme radius ratios may need a smaller tolerance. The benchmark checks the
choice on a scene held out of the table (``warp_lamp.bench.tolerance.check_tolerance``). The wetted surface
(``surfaces="all"``) models another surface and is not chosen by ``tolerance``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import warp as wp

from warp_lamp.validate import check_positive

__all__ = ["MARGIN", "TABLE_PATH", "LampChoice", "choose_settings", "device_kind", "load_table"]

#: How far below the tolerance a setting's table error must lie (rule 2 of the module docstring).
MARGIN = 1.2
#: The speed-error table the package ships.
TABLE_PATH = Path(__file__).resolve().parent / "data" / "speed_error.json"


@dataclass(frozen=True)
class LampChoice:
    """What ``tolerance=`` chose, and why.

    Attributes:
        tolerance: The tolerance asked for (a fraction: 0.01 is 1%).
        criterion: 1 or ``"area"``.
        cells_per_diameter: Cells per mean particle diameter.
        resolver: Area criterion's resolver (None for criterion 1).
        depth_slots: Area criterion's slots (None for criterion 1).
        subpoints: Sub-point resolver's points per cell edge (None otherwise).
        gather: Area criterion's gather, ``"front"`` or ``"deep"`` (None for criterion 1).
        error: The setting's error in the table (the largest RMS over its scenes).
        time_ratio: Its update time over criterion 1 at 4 cells per diameter, on ``kind``.
        kind: The device kind whose times decided.
    """

    tolerance: float
    criterion: int | str
    cells_per_diameter: float
    resolver: str | None
    depth_slots: int | None
    subpoints: int | None
    error: float
    time_ratio: float
    kind: str
    gather: str | None = None

    def options(self) -> dict:
        """The lamp keywords of the choice (``criterion`` and, for the area criterion, its resolver settings)."""
        out = {"criterion": self.criterion}
        if self.criterion == "area":
            out.update(resolver=self.resolver, depth_slots=self.depth_slots)
            if self.subpoints is not None:
                out["subpoints"] = self.subpoints
            if self.gather is not None:
                out["gather"] = self.gather
        return out

    def describe(self) -> str:
        """One line for people: what was chosen, its table error and its cost."""
        if self.criterion == "area":
            extra = f", D = {self.depth_slots}" + (f", S = {self.subpoints}" if self.subpoints else "")
            extra += ", deep gather" if self.gather == "deep" else ""
            what = f"area criterion ({self.resolver}{extra})"
        else:
            what = "criterion 1"
        return (
            f"tolerance {self.tolerance:.3g}: {what} at {self.cells_per_diameter:g} cells per diameter "
            f"(table error {100 * self.error:.3g}%, {self.time_ratio:.3g}x criterion 1 at 4 on {self.kind})"
        )


@cache
def load_table(path: str | None = None) -> dict:
    """The speed-error table (the package's by default)."""
    with open(path or TABLE_PATH, encoding="utf-8") as f:
        return json.load(f)


def device_kind(device, table: dict) -> str:
    """The table's device kind whose times stand for ``device``: its own name if measured (e.g. ``"h100"``),
    else the table's first CUDA kind for a GPU, or ``"cpu"``."""
    d = wp.get_device(device)
    kinds = list(table["kinds"])
    if not d.is_cuda:
        return "cpu"
    name = d.name.lower()
    for k in kinds:
        if k != "cpu" and k in name:
            return k
    cuda = [k for k in kinds if k != "cpu"]
    return cuda[0] if cuda else "cpu"


def choose_settings(tolerance, device=None, *, table: dict | None = None, margin: float = MARGIN) -> LampChoice:
    """The cheapest setting whose table error times ``margin`` is at most ``tolerance`` (the module's rule).

    Args:
        tolerance: Largest acceptable RMS per-particle force error, as a fraction of P pi rbar^2 (0.01 is 1%).
        device: The device the lamp will run on (its kind decides the times).
        table: A speed-error table (the package's by default).
        margin: The factor of rule 2 (:data:`MARGIN`).

    Raises:
        ValueError: naming ``tolerance`` when it is not a number > 0, or tighter than any setting in the table
            reaches (with the best the table has).
    """
    tol = check_positive("tolerance", tolerance)
    table = load_table() if table is None else table
    kind = device_kind(device, table)
    rows = [r for r in table["rows"] if margin * r["error"] <= tol and r["ratio"].get(kind) is not None]
    if not rows:
        best = min(table["rows"], key=lambda r: r["error"])
        raise ValueError(
            f"tolerance: {tol:.3g} is tighter than any setting in the speed-error table reaches with its margin of "
            f"{margin:g} (best {best['error']:.3g}: {best['criterion']} at {best['cells_per_diameter']:g} cells per "
            "diameter); "
            "choose the settings yourself: criterion 1 at more cells per diameter (its error falls about as "
            "cells_per_diameter**-1.5, its time grows as its square) or criterion='area', resolver='exact', "
            "depth_slots=5, gather='deep' (to 0.01% on random packings, 0.3% on the table's lattice balls)"
        )
    r = min(rows, key=lambda r: (r["ratio"][kind], r["error"]))
    return LampChoice(
        tolerance=tol,
        criterion=r["criterion"],
        cells_per_diameter=float(r["cells_per_diameter"]),
        resolver=r.get("resolver"),
        depth_slots=r.get("depth_slots"),
        subpoints=r.get("subpoints"),
        error=float(r["error"]),
        time_ratio=float(r["ratio"][kind]),
        kind=kind,
        gather=r.get("gather", "front") if r["criterion"] == "area" else None,
    )
