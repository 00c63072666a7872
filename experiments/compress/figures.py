"""Thesis ch.3 figures 3.2 and 3.4–3.12, and umbrella vs Karni–Gotsman at equal r.

    .venv/bin/python experiments/compress/figures.py [--quick]

* fig 3.2: a 3 000-vertex bunny (quadric-decimated) and its spectral
  coefficients c = B^T v per axis, all m of them (umbrella: eq.5 coefficients);
* figs 3.4–3.7: renders at several r, Laplacian (Karni–Gotsman) vs umbrella, on
  the bunny, the camel head (the thesis's camel is not among the shared meshes)
  and the fandisk (standing in for the femur); fig 3.5 is the bunny's head at r = 125;
* fig 3.8: the Cauchy weight g(x) = 1/(1 + x²/c²), c = 2.3849;
* fig 3.9: the two rings of a vertex that D needs;
* figs 3.10–3.12: D (eq.6) and E (ch.2 eq.13) against r for the three meshes;
* ``umbrella_vs_laplacian.md``: D and E of both bases at equal r on ten shared
  meshes (whole-mesh bases), and inside the codec (METIS patches, keep 5% / 10%).

Every mesh is first scaled to a unit bounding-box diagonal (D's Cauchy constant is
an absolute length).  One basis per mesh and kind is computed with the largest r
and its leading columns are used for smaller r (the bases are nested).
Writes ``experiments/results/compress/figures/``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import ROOT, load, timed  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.compress import project, project_orthonormal, spectral_basis  # noqa: E402
from jaxmesh.render import render  # noqa: E402
from jaxmesh.metrics import CAUCHY_C, nonlinear_visual_error, visual_error  # noqa: E402

OUT = ROOT / "experiments" / "results" / "compress" / "figures"
KINDS = ("laplacian", "umbrella")
LABEL = {"laplacian": "Laplacian (Karni–Gotsman)", "umbrella": "umbrella (thesis)"}


def unit(mesh):
    return jaxmesh.normalize(mesh)


def reconstruct(mesh, vecs: np.ndarray, kind: str):
    b = jax.numpy.asarray(vecs)
    x = project_orthonormal(b, mesh.vertices) if kind == "laplacian" else project(b, mesh.vertices)
    return mesh.with_vertices(x)


def bases(mesh, r_max: int) -> dict:
    out = {}
    for kind in KINDS:
        b, t = timed(spectral_basis, mesh, r_max, kind)
        print(f"    {kind} basis r={b.r} in {t:.1f} s", flush=True)
        out[kind] = b.vectors
    return out


def errors(mesh, rec) -> tuple[float, float]:
    return float(nonlinear_visual_error(mesh, rec)), float(visual_error(mesh, rec))


def decimated_bunny(target: int = 3000):
    import fast_simplification

    m = load("bunny")
    v = np.array(m.vertices, order="C")
    f = np.array(m.faces, dtype=np.int32, order="C")
    v2, f2 = fast_simplification.simplify(v, f, target_reduction=1 - target / len(v))
    used = np.unique(f2)
    remap = np.full(len(v2), -1)
    remap[used] = np.arange(len(used))
    return unit(jaxmesh.Mesh.from_arrays(v2[used], remap[f2], warn=False))


def fig_coefficients(plt) -> None:
    mesh = decimated_bunny()
    fig, axes = plt.subplots(2, 4, figsize=(16, 7))
    for row, kind in enumerate(KINDS):
        b = spectral_basis(mesh, mesh.num_vertices, kind).vectors
        c = np.linalg.lstsq(b, np.asarray(mesh.vertices), rcond=None)[0]
        render(mesh, ax=axes[row, 0], title=f"bunny, {mesh.num_vertices} vertices")
        for k, axis in enumerate("xyz"):
            ax = axes[row, k + 1]
            ax.plot(c[:, k], lw=0.5)
            ax.set_title(f"{LABEL[kind]}: c_{axis}")
            ax.set_xlabel("index i (increasing frequency)")
    fig.tight_layout()
    fig.savefig(OUT / "fig3_2_coefficients.png", dpi=100)
    plt.close(fig)


def fig_renders(plt, name: str, mesh, vecs: dict, rs, fig_id: str, up: str = "y", azim: float = 20.0) -> None:
    fig, axes = plt.subplots(2, len(rs) + 1, figsize=(3.2 * (len(rs) + 1), 6.4))
    for row, kind in enumerate(KINDS):
        render(mesh, ax=axes[row, 0], title="original", up=up, azim=azim)
        for j, r in enumerate(rs):
            rec = reconstruct(mesh, vecs[kind][:, :r], kind)
            d, e = errors(mesh, rec)
            render(rec, ax=axes[row, j + 1], up=up, azim=azim,
                                  title=f"{LABEL[kind]}\nr = {r}: D = {d:.2e}")
    fig.tight_layout()
    fig.savefig(OUT / f"fig{fig_id}_{name}_renders.png", dpi=100)
    plt.close(fig)


def fig_closeup(plt, mesh, vecs: dict, r: int = 125) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.5))
    v = np.asarray(mesh.vertices)
    mid = 0.5 * (v.min(0) + v.max(0))  # one frame for all three panels
    window = None
    for ax, (title, m) in zip(axes, [("original", mesh)] + [
            (f"{LABEL[k]}, r = {r}", reconstruct(mesh, vecs[k][:, :r], k)) for k in KINDS]):
        render(m, ax=ax, title=title, center=mid)
        if window is None:
            x0, x1 = ax.get_xlim()
            y0, y1 = ax.get_ylim()
            window = ((x0, x0 + 0.45 * (x1 - x0)), (y0 + 0.5 * (y1 - y0), y1))  # the head, upper left
        ax.set_xlim(*window[0])
        ax.set_ylim(*window[1])
    fig.tight_layout()
    fig.savefig(OUT / "fig3_5_bunny_head_r125.png", dpi=100)
    plt.close(fig)


def fig_cauchy(plt) -> None:
    x = np.linspace(0, 10, 400)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.plot(x, 1 / (1 + (x / CAUCHY_C) ** 2))
    ax.set_title(f"Cauchy weight g(x), c = {CAUCHY_C}")
    ax.set_xlabel("x")
    ax.set_ylabel("g(x)")
    fig.tight_layout()
    fig.savefig(OUT / "fig3_8_cauchy.png", dpi=100)
    plt.close(fig)


def fig_two_rings(plt) -> None:
    """A triangulated hexagonal patch: vertex i, its 1-ring v_i* and the 2-ring."""
    import matplotlib.tri as mtri

    pts = [(a + 0.5 * b, b * np.sqrt(3) / 2) for a in range(-3, 4) for b in range(-3, 4) if abs(a + b) <= 3]
    p = np.array(pts)
    tri = mtri.Triangulation(p[:, 0], p[:, 1])
    dist = np.round(np.linalg.norm(p, axis=1), 6)
    hop = np.where(dist == 0, 0, np.where(dist <= 1.0001, 1, np.where(dist <= 2.0001, 2, 3)))
    fig, ax = plt.subplots(figsize=(5, 4.5))
    ax.triplot(tri, color="0.7", lw=0.8)
    for h, col, lab in ((0, "k", "v_i"), (1, "tab:red", "1-ring v_j ∈ v_i*"), (2, "tab:blue", "2-ring v_k ∈ v_j*")):
        sel = hop == h
        ax.scatter(p[sel, 0], p[sel, 1], color=col, s=40 if h else 80, label=lab, zorder=3)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("D needs two rings: A(v_i) uses |grad v_j|, which uses v_j's neighbours")
    fig.tight_layout()
    fig.savefig(OUT / "fig3_9_two_rings.png", dpi=100)
    plt.close(fig)


def curves(mesh, vecs: dict, rs) -> dict:
    out = {}
    for kind in KINDS:
        out[kind] = [errors(mesh, reconstruct(mesh, vecs[kind][:, :r], kind)) for r in rs]
    return out


def fig_curves(plt, name: str, rs, res: dict, fig_id: str) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    for k, what in enumerate(("D (eq.6)", "E (visual error)")):
        for kind in KINDS:
            axes[k].plot(rs, [x[k] for x in res[kind]], "o-", ms=3, label=LABEL[kind])
        axes[k].set_yscale("log")
        axes[k].set_xlabel("r (basis vectors)")
        axes[k].set_title(f"{name}: {what}")
        axes[k].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / f"fig{fig_id}_{name}_error_vs_r.png", dpi=100)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small meshes and r only (a smoke run)")
    args = ap.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    OUT.mkdir(parents=True, exist_ok=True)
    fig_cauchy(plt)
    fig_two_rings(plt)
    print("fig 3.2", flush=True)
    fig_coefficients(plt)
    rs_fig = (25, 125, 300)
    rs_curve = (10, 15, 25, 40, 60, 100, 150, 200, 300)
    table_meshes = ("eight", "cow", "spot", "fertility", "maxplanck", "fandisk", "shark", "human", "camelhead",
                    "bunny")
    figure_meshes = {"bunny": ("3_4", "3_10", "y", 20.0), "camelhead": ("3_6", "3_11", "y", 60.0),
                     "fandisk": ("3_7", "3_12", "y", 30.0)}
    if args.quick:
        table_meshes, rs_curve, rs_fig = ("eight", "cow"), (10, 25, 60), (10, 60)
        figure_meshes = {"cow": ("3_4", "3_10", "y", 20.0)}
    results = {"r": list(rs_curve), "meshes": {}}
    for name in table_meshes:
        mesh = unit(load(name))
        print(f"{name}: {mesh.num_vertices} vertices", flush=True)
        vecs = bases(mesh, max(rs_curve))
        res = curves(mesh, vecs, rs_curve)
        results["meshes"][name] = res
        if name in figure_meshes:
            fr, fc, up, azim = figure_meshes[name]
            fig_renders(plt, name, mesh, vecs, rs_fig, fr, up=up, azim=azim)
            fig_curves(plt, name, rs_curve, res, fc)
            if name == "bunny":
                fig_closeup(plt, mesh, vecs)
    results["codec"] = codec_comparison(("fandisk", "bunny", "armadillo") if not args.quick else ("cow",))
    (OUT / "umbrella_vs_laplacian.json").write_text(json.dumps(results, indent=1))
    write_table(results)


def codec_comparison(names) -> list[dict]:
    rows = []
    for name in names:
        mesh = unit(load(name))
        v = np.asarray(mesh.vertices)
        for keep in (0.05, 0.1):
            for kind in KINDS:
                c = jaxmesh.compress.compress(mesh, keep=keep, bits=16, basis=kind)
                # the original, in the decoded vertex order and face list
                ref = jaxmesh.Mesh.from_arrays(v[c.order], np.asarray(c.mesh.faces), warn=False)
                d, e = errors(ref, c.mesh)
                rms = float(np.sqrt(np.mean(np.sum((v[c.order] - np.asarray(c.mesh.vertices)) ** 2, 1))))
                rows.append({"mesh": name, "keep": keep, "basis": kind, "D": d, "E": e, "vertex_rms": rms,
                             "bpv": c.bits_per_vertex})
                print(f"  codec {name} keep {keep} {kind}: D {d:.3e} E {e:.3e} rms {rms:.3e}", flush=True)
    return rows


def write_table(results) -> None:
    rs = results["r"]
    lines = ["# Umbrella (thesis) vs Laplacian (Karni–Gotsman) bases at equal r", "",
             "Generated by `experiments/compress/figures.py`. Meshes scaled to a unit bounding-box diagonal; "
             "whole-mesh bases; eq.5 projection for the umbrella basis, B Bᵀ V for the orthonormal Laplacian "
             "basis. Each cell: D_umbrella / D_laplacian (below 1: the umbrella basis is better).", "",
             "| mesh | " + " | ".join(f"r = {r}" for r in rs) + " | umbrella better (D) | umbrella better (E) |",
             "|---|" + "---|" * (len(rs) + 2)]
    tot = [0, 0, 0]
    for name, res in results["meshes"].items():
        ratio_d = [u[0] / lap[0] for u, lap in zip(res["umbrella"], res["laplacian"])]
        ratio_e = [u[1] / lap[1] for u, lap in zip(res["umbrella"], res["laplacian"])]
        wins_d = sum(x < 1 for x in ratio_d)
        wins_e = sum(x < 1 for x in ratio_e)
        tot[0] += wins_d
        tot[1] += wins_e
        tot[2] += len(rs)
        lines.append(f"| {name} | " + " | ".join(f"{x:.3f}" for x in ratio_d)
                     + f" | {wins_d}/{len(rs)} | {wins_e}/{len(rs)} |")
    lines += ["", f"Umbrella better in D in **{tot[0]} of {tot[2]}** cases, in E in **{tot[1]} of {tot[2]}**.", "",
              "## Inside the codec (default METIS patches: 100/keep vertices, 1000–3000; 16-bit quantization)", "",
              "| mesh | keep | basis | D | E | vertex RMS | bits/vertex |", "|---|---|---|---|---|---|---|"]
    for r in results["codec"]:
        lines.append(f"| {r['mesh']} | {r['keep']} | {r['basis']} | {r['D']:.3e} | {r['E']:.3e} | "
                     f"{r['vertex_rms']:.3e} | {r['bpv']:.2f} |")
    (OUT / "umbrella_vs_laplacian.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
