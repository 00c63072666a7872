"""Rebuild the mesh-info table for every mesh in ../shared/meshes and compare it
with MANIFEST.md.  Writes experiments/results/info_table.md.

    .venv/bin/python experiments/info_table.py [--meshes ../shared/meshes]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import jaxmesh

COLUMNS = ["vertices", "faces", "edges", "boundary_edges", "boundary_loops", "components",
           "euler_characteristic", "genus", "manifold", "non_manifold_edges", "non_manifold_vertices",
           "duplicate_vertices", "degenerate_faces", "mean_edge_length", "bbox_diagonal"]


def main() -> None:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--meshes", type=Path, default=here.parents[1] / "shared" / "meshes")
    ap.add_argument("--out", type=Path, default=here / "results" / "info_table.md")
    args = ap.parse_args()
    files = sorted(args.meshes.glob("*.ply")) + sorted((args.meshes / "defects").glob("*.ply"))
    if not files:
        raise SystemExit(f"no meshes under {args.meshes}")
    lines = ["| mesh | " + " | ".join(COLUMNS) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    for f in files:
        info = jaxmesh.mesh_info(jaxmesh.load(f))
        cells = []
        for c in COLUMNS:
            v = info[c]
            cells.append(f"{v:.6g}" if isinstance(v, float) else ("—" if v is None else str(v)))
        lines.append(f"| {f.relative_to(args.meshes)} | " + " | ".join(cells) + " |")
    text = ("# `jaxmesh info` on the shared meshes\n\nRegenerate: "
            "`.venv/bin/python experiments/info_table.py`. Counts equal MANIFEST.md "
            "(checked by tests/test_topology.py).\n\n" + "\n".join(lines) + "\n")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
