"""Thesis figs 2.5 and 2.14 and the stability study: E against λ for the kernel
flow (1, 2, 5, 10 iterations), and E against the iteration count (1…30) for
the kernel flow and the Laplacian-type baselines at fixed parameters.

    .venv/bin/python experiments/denoise/curves.py [--meshes bunny fandisk cow]

writes experiments/results/denoise/e_vs_lambda.png, e_vs_iterations.png and
curves.csv.
"""

from __future__ import annotations

import argparse
import csv

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from common import LOG, METHODS, RESULTS, SIGMAS, jnp, load, noisy_copy, np, visual_error  # noqa: E402

ITERATION_METHODS = {
    "kernel (λ=0.4)": ("kernel", {"lam": 0.4}),
    "kernel, paper eq.7 (λ=0.4)": ("kernel", {"lam": 0.4, "variant": "paper"}),
    "umbrella flow (λ=0.5)": ("umbrella_flow", {"lam": 0.5}),
    "taubin (0.5, -0.53)": ("taubin", {}),
    "cauchy diffusion (dt=0.25, c=1)": ("cauchy_diffusion", {}),
    "hc (0.1, 0.5)": ("hc", {}),
}
ITERATIONS = (1, 2, 3, 5, 8, 12, 16, 20, 25, 30)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--meshes", nargs="+", default=["bunny", "fandisk", "cow"])
    args = ap.parse_args()
    RESULTS.mkdir(parents=True, exist_ok=True)
    lams = LOG(-1.5, 1.5, 40)
    rows = []
    fig, axes = plt.subplots(len(args.meshes), len(SIGMAS), figsize=(4 * len(SIGMAS), 3.2 * len(args.meshes)),
                             squeeze=False)
    fig2, axes2 = plt.subplots(len(args.meshes), len(SIGMAS), figsize=(4 * len(SIGMAS), 3.2 * len(args.meshes)),
                               squeeze=False)
    for i, name in enumerate(args.meshes):
        clean = load(name)
        for j, sigma in enumerate(SIGMAS):
            noisy = noisy_copy(clean, sigma)
            e0 = float(visual_error(clean, noisy))
            batch = noisy.with_vertices(jnp.broadcast_to(noisy.vertices, (len(lams),) + noisy.vertices.shape))
            ax = axes[i, j]
            for it in (1, 2, 5, 10):
                e = np.asarray(visual_error(clean, METHODS["kernel"](batch, lam=jnp.asarray(lams),
                                                                       iterations=it))) / e0
                ax.loglog(lams, e, label=f"{it} it.")
                k = int(np.argmin(e))
                ax.plot(lams[k], e[k], "k.", ms=5)
                rows += [{"figure": "e_vs_lambda", "mesh": name, "sigma": sigma, "iterations": it,
                          "lam": float(l), "E_ratio": float(x)} for l, x in zip(lams, e)]
            ax.axhline(1, color="gray", lw=0.5)
            ax.set_title(f"{name}, σ = {sigma} mean edge", fontsize=9)
            ax.set_xlabel("λ")
            ax.set_ylabel("E / E(noisy)")
            ax2 = axes2[i, j]
            for label, (method, params) in ITERATION_METHODS.items():
                es = []
                for it in ITERATIONS:
                    out = METHODS[method](noisy, iterations=it, **params)
                    es.append(float(visual_error(clean, out)) / e0)
                    rows.append({"figure": "e_vs_iterations", "mesh": name, "sigma": sigma, "method": label,
                                 "iterations": it, "E_ratio": es[-1]})
                ax2.semilogy(ITERATIONS, es, label=label, marker=".")
            ax2.axhline(1, color="gray", lw=0.5)
            ax2.set_title(f"{name}, σ = {sigma} mean edge", fontsize=9)
            ax2.set_xlabel("iterations")
            ax2.set_ylabel("E / E(noisy)")
            print(f"{name} σ={sigma} done", flush=True)
    axes[0, 0].legend(fontsize=7)
    axes2[0, 0].legend(fontsize=6)
    fig.suptitle("Kernel flow: visual error against λ (dots: optimum)", fontsize=10)
    fig2.suptitle("Visual error against the number of iterations (stability)", fontsize=10)
    fig.tight_layout()
    fig2.tight_layout()
    fig.savefig(RESULTS / "e_vs_lambda.png", dpi=110)
    fig2.savefig(RESULTS / "e_vs_iterations.png", dpi=110)
    keys = sorted({k for r in rows for k in r})
    with open(RESULTS / "curves.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
