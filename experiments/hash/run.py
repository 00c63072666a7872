"""Tables 4.1 (robustness) and 4.2 (uniqueness) of the thesis for the thesis's hash
and the robust hash, with the separation margin, on the shared meshes.

    .venv/bin/python experiments/hash/run.py [--meshes cow spot ...] [--seed 0]

Writes experiments/results/hash/{README.md, results.json, partition.png}.

* Robustness: ρ(h(M), h(attack(M))) for every attack of ``jaxmesh.hashing.attacks``
  (the thesis's table 4.1 and three more), attack seed ``--seed``.
* Uniqueness: ρ(h(A), h(B)) over every pair of different meshes.
* Margin = smallest robustness ρ − largest cross-model ρ, over the table 4.1
  attacks and over all attacks.  Positive = a threshold separates them.
* Why the thesis's rotation ρ was not 1: ρ between hashes of the same mesh made
  with other METIS seeds (the partition changes; the geometry does not).
* Time of one hash per mesh (single run, 2-core CPU where this was run).
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import jaxmesh  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import MESHES, load, timed  # noqa: E402
from jaxmesh.hashing import attacks  # noqa: E402
from jaxmesh.hashing import HASHES, THRESHOLDS, cosine_similarity, mesh_hash, similarity  # noqa: E402
from jaxmesh.hashing.robust import HALF_DISTANCE  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "experiments" / "results" / "hash"






def table(rows: list[str], cols: list[str], cell, fmt="{:.4f}") -> str:
    out = ["| | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for r in rows:
        out.append(f"| {r} | " + " | ".join(fmt.format(cell(r, c)) for c in cols) + " |")
    return "\n".join(out)


def partition_figure(mesh: jaxmesh.Mesh, h, path: Path, title: str) -> None:
    """Fig 4.4 analogue: the METIS parts in canonical order, one colour each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from jaxmesh.render import view_rotation

    v = np.asarray(mesh.vertices)
    f = np.asarray(mesh.faces)
    v = (v - v.mean(0)) @ view_rotation(15, 30).T
    tri = v[f]
    order = np.argsort(tri[:, :, 2].mean(1))
    face_part = h.labels[f[:, 0]]
    colours = plt.get_cmap("tab10")(face_part % 10)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    shade = np.abs(n[:, 2]) / np.maximum(np.linalg.norm(n, axis=1), 1e-300)
    colours[:, :3] *= (0.35 + 0.65 * shade)[:, None]
    fig, ax = plt.subplots(figsize=(5, 5))
    ax.add_collection(PolyCollection(tri[order][:, :, :2], facecolors=colours[order], edgecolors="none"))
    ax.autoscale()
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=9)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=list(MESHES))
    ap.add_argument("--seed", type=int, default=0, help="seed of the random attacks")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)

    meshes = {name: load(name) for name in args.meshes}
    base: dict[str, dict] = {k: {} for k in HASHES}
    times: dict[str, dict] = {k: {} for k in HASHES}
    rob: dict[str, dict] = {k: {} for k in HASHES}
    seeds_rho: dict[str, list] = {}
    for name, mesh in tqdm(meshes.items(), desc="meshes"):
        for kind, fn in HASHES.items():
            base[kind][name], times[kind][name] = timed(fn, mesh)
        for att_name, attack in attacks.ALL_ATTACKS.items():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", jaxmesh.MeshWarning)
                attacked = attack(mesh, args.seed)
            for kind, fn in HASHES.items():
                rob[kind][(name, att_name)] = similarity(base[kind][name], fn(attacked))
        seeds_rho[name] = [cosine_of_seeds(mesh, base["thesis"][name], s) for s in (1, 2, 3)]

    cross = {kind: {(a, b): similarity(base[kind][a], base[kind][b])
                    for a, b in itertools.combinations(meshes, 2)} for kind in HASHES}
    # the robust hash's raw distances, to check HALF_DISTANCE still sits in the gap
    dist_rob = {k: -HALF_DISTANCE * np.log2(v) for k, v in rob["robust"].items()}
    dist_cross = {k: -HALF_DISTANCE * np.log2(v) for k, v in cross["robust"].items()}

    names = list(meshes)
    att_all = list(attacks.ALL_ATTACKS)
    att_41 = list(attacks.TABLE_4_1)
    summary: dict = {"margin": {}, "worst": {}}
    lines = ["# Mesh hashing: robustness (table 4.1) and uniqueness (table 4.2)", "",
             f"Made by `experiments/hash/run.py` (attack seed {args.seed}); rerun it to reproduce.", "",
             "Attacks (`jaxmesh.hashing.attacks`; the thesis does not give its scaling factor, smoothing step",
             "or noise unit, so these are the choices):", ""]
    for att_name, attack in attacks.ALL_ATTACKS.items():
        tag = "table 4.1" if att_name in attacks.TABLE_4_1 else "extra"
        lines.append(f"- `{att_name}` ({tag}): `{attack.__doc__}`")
    lines += ["", "Noise σ is relative to the mean edge length ℓ̄; scaling and rotation are about the",
              "origin; `crop` removes the 2 % of vertices nearest a random vertex with their faces.", ""]
    for kind in HASHES:
        r41 = {k: v for k, v in rob[kind].items() if k[1] in att_41}
        worst41 = min(r41, key=r41.get)
        worst_all = min(rob[kind], key=rob[kind].get)
        best_cross = max(cross[kind], key=cross[kind].get)
        m41 = r41[worst41] - cross[kind][best_cross]
        mall = rob[kind][worst_all] - cross[kind][best_cross]
        summary["margin"][kind] = {"table_4_1": m41, "all_attacks": mall}
        summary["worst"][kind] = {"robustness_4_1": [*worst41, r41[worst41]],
                                  "robustness_all": [*worst_all, rob[kind][worst_all]],
                                  "cross": [*best_cross, cross[kind][best_cross]]}
        params = base[kind][names[0]].params
        lines += [f"## `{kind}` hash — parameters {params}", "",
                  f"**Separation margin** (smallest robustness ρ − largest cross-model ρ): "
                  f"**{m41:+.4f}** over the table 4.1 attacks "
                  f"(worst: {worst41[0]} / {worst41[1]} ρ = {r41[worst41]:.4f}; "
                  f"closest pair: {best_cross[0]}–{best_cross[1]} ρ = {cross[kind][best_cross]:.4f}); "
                  f"**{mall:+.4f}** over all attacks (worst: {worst_all[0]} / {worst_all[1]}). "
                  f"Verdict threshold: ρ ≥ {THRESHOLDS[kind]}.", "",
                  f"### Table 4.1 analogue — robustness ρ ({kind})", "",
                  table(att_all, names, lambda a, n: rob[kind][(n, a)]), "",
                  f"### Table 4.2 analogue — cross-model ρ ({kind})", "",
                  table(names, names, lambda a, b: 1.0 if a == b else
                        cross[kind][(a, b) if (a, b) in cross[kind] else (b, a)]), ""]
    lines += ["## Why the thesis's rotation ρ was not 1", "",
              "Rotation changes no length, angle or area, and METIS sees only the connectivity, so",
              "the thesis's construction gives ρ = 1 under rotation (measured above: "
              f"min over meshes {min(rob['thesis'][(n, a)] for n in names for a in att_41 if 'rotate' in a):.12f}).",
              "The thesis's rotation rows are identical for x, y and z (0.9534 on the camel for all",
              "three), so whatever lowered them did not depend on the rotation: the likeliest cause is",
              "a different partition of the attacked copy (METIS is randomised; a rotated copy saved",
              "and reloaded by another tool can also come back with its vertices renumbered).  The",
              "same mesh hashed with other METIS seeds gives, here:", "",
              "| mesh | seed 1 | seed 2 | seed 3 |", "|---|---|---|---|"]
    for n in names:
        lines.append(f"| {n} | " + " | ".join(f"{x:.4f}" for x in seeds_rho[n]) + " |")
    lines += ["", "and vertex reordering (row `reorder` above) has the same effect.", "",
              "## Robust hash: the distance scale", "",
              f"ρ = 2^(−d / d½) with d½ = {HALF_DISTANCE}.  Measured here: largest distance under the "
              f"table 4.1 attacks {max(v for k, v in dist_rob.items() if k[1] in att_41):.4f}, under all "
              f"attacks {max(dist_rob.values()):.4f}; smallest between models "
              f"{min(dist_cross.values()):.4f}.", "",
              "## Time per hash (seconds, one run, this machine)", "",
              table(names, list(HASHES), lambda n, k: times[k][n], "{:.2f}"), ""]
    (OUT / "README.md").write_text("\n".join(lines))
    (OUT / "results.json").write_text(json.dumps({
        "seed": args.seed, "summary": summary,
        "robustness": {k: {f"{n}|{a}": v for (n, a), v in d.items()} for k, d in rob.items()},
        "cross": {k: {f"{a}|{b}": v for (a, b), v in d.items()} for k, d in cross.items()},
        "metis_seed_rho": seeds_rho, "seconds": times,
        "robust_distance": {"attacks_4_1_max": max(v for k, v in dist_rob.items() if k[1] in att_41),
                            "attacks_all_max": max(dist_rob.values()),
                            "cross_min": min(dist_cross.values())},
    }, indent=1))
    for name in ("cow", "bunny"):
        if name in meshes:
            partition_figure(meshes[name], base["thesis"][name], OUT / f"partition_{name}.png",
                             f"{name}: 8 METIS parts, canonical order (tab10 colours 0..7)")
    print(json.dumps(summary, indent=1))


def cosine_of_seeds(mesh, h0, seed: int) -> float:
    """ρ (eq.4) between ``h0`` and the same mesh's hash under another METIS seed."""
    h1 = mesh_hash(mesh, seed=seed)
    return cosine_similarity(*(np.exp(h.log_vector - h.log_vector.max()) for h in (h0, h1)))


if __name__ == "__main__":
    main()
