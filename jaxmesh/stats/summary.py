"""Everything of ch.5 for one mesh in one call, and the thesis's six-panel figure
(figs 5.2–5.19: render, spectrum, degree distribution, assortativity,
clustering, geodesic distances)."""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from .._threads import concurrent_map
from ..mesh import Mesh, MeshWarning
from ._graph import graph_view
from .clustering import clustering, clustering_by_degree, thesis_clustering
from .degree import (assortativity_function, average_degree, degree_assortativity, degree_distribution,
                     neighbor_connectivity)
from .geodesic import distance_histogram, sample_sources
from .spectrum import DENSE_MAX, laplacian_spectrum

__all__ = ["mesh_statistics", "plot_statistics", "SOURCES", "KNN", "CONCURRENT_VERTICES"]


#: the defaults of :func:`mesh_statistics`'s ``sources`` and ``knn`` (lowered quietly on a small mesh)
SOURCES, KNN = 200, 8
#: meshes up to this many vertices get their geodesics and spectra on threads side by side
CONCURRENT_VERTICES = 50_000


def mesh_statistics(mesh: Mesh, sources: int | None = None, seed: int = 0, knn: int | None = None,
                    spectrum_k: int | None = None, geodesics: tuple[str, ...] = ("edges", "knn", "heat"),
                    dense_max: int = DENSE_MAX, progress: Callable[[str], None] | None = None) -> dict:
    """All ch.5 statistics of ``mesh``.

    Arguments:
        mesh: the mesh (single).
        sources: geodesic sources, sampled from ``seed`` (default :data:`SOURCES`, at most V;
            a given count above V: every vertex, with a :class:`~jaxmesh.MeshWarning`; the
            memory stays that of a few sources).
        seed: the seed of the source sample.
        knn: neighbours of the kNN graph (default :data:`KNN`, at most V − 1; a given count
            above V − 1: the complete graph, with a warning).
        spectrum_k: exact eigenvalues at each end of the spectra (default None: the whole
            spectrum: exact up to ``dense_max`` vertices, else estimated; :func:`laplacian_spectrum`).
        geodesics: the geodesic methods: ``"edges"``, ``"knn"``, ``"heat"``.
        dense_max: meshes up to this many vertices get both whole spectra from a dense
            eigensolver (cubic in V; default :data:`~jaxmesh.stats.DENSE_MAX`).
        progress: called with the name of each stage before it runs (the CLI prints it).

    Returns:
        A dict: ``summary`` (scalars) and the arrays (degree distribution, K_nn(k),
        C(k) both ways, spectra; ``geodesics``: each method's
        :class:`~jaxmesh.stats.DistanceHistogram`, reduced a few sources at a time so that
        no (S, V) array is held)."""
    say = progress or (lambda stage: None)
    for name, value in (("sources", sources), ("knn", knn)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1):
            raise ValueError(f"{name} must be a positive int, got {value!r}")
    if isinstance(dense_max, bool) or not isinstance(dense_max, (int, np.integer)) or dense_max < 0:
        raise ValueError(f"dense_max must be a non-negative int, got {dense_max!r}")
    n = mesh.num_vertices
    if sources is None:
        sources = SOURCES                 # sample_sources takes every vertex of a smaller mesh
    elif sources > n:
        warnings.warn(f"sources={sources} is more than the mesh's {n} vertices: every vertex is a source",
                      MeshWarning, stacklevel=2)
    if knn is None:
        knn = KNN
    elif knn > n - 1 and "knn" in geodesics:
        warnings.warn(f"knn={knn} is more than the other {n - 1} vertices: the kNN graph is complete",
                      MeshWarning, stacklevel=2)
    src = sample_sources(mesh, sources, seed)
    dist, spec, parts = _concurrent_parts(mesh, src, geodesics, knn, (spectrum_k, dense_max), say)
    graph, c, ct = parts["graph"], parts["clustering"], parts["thesis_clustering"]
    d = graph.degree
    connected = d > 0
    differ = connected & ~np.isclose(c, np.nan_to_num(ct, nan=-1))
    summary = {
        "vertices": mesh.num_vertices,
        "average_degree": average_degree(graph),
        "degree_6_share": float(np.mean(d == 6)),
        "assortativity": degree_assortativity(graph),
        "mean_clustering": float(np.mean(c)),
        "mean_thesis_clustering": float(np.nanmean(ct)),
        "clustering_formulas_differ_at": int(differ.sum()),
        "sources": int(len(src)),
        "seed": seed,
        "spectrum": ("exact" if spectrum_k is None and mesh.num_vertices <= dense_max else
                     "estimated (kernel polynomial method)" if spectrum_k is None else f"{spectrum_k} at each end"),
    }
    for g, h in dist.items():
        summary[f"geodesic_{g}_mean"], summary[f"geodesic_{g}_std"] = h.mean, h.std
    return {"summary": summary, "degree": parts["degree"], "knn": parts["knn"], "clustering": parts["clustering_k"],
            "thesis_clustering": parts["thesis_clustering_k"], "spectrum": spec, "geodesics": dist, "sources": src}


def _graph_statistics(mesh) -> dict:
    """The edge graph's statistics: degrees, K_nn, both clusterings and their C(k)."""
    graph = graph_view(mesh)      # the host edge graph, once for every statistic below
    knn_v = neighbor_connectivity(graph)
    c, ct = clustering(graph), thesis_clustering(graph)
    ck, c_k = clustering_by_degree(graph, c)
    _, ct_k = clustering_by_degree(graph, ct)
    return {"graph": graph, "degree": degree_distribution(graph), "knn": assortativity_function(graph, knn_v),
            "clustering": c, "thesis_clustering": ct, "clustering_k": (ck, c_k), "thesis_clustering_k": (ck, ct_k)}


def _concurrent_parts(mesh, src, geodesics, knn, spectra, say) -> tuple[dict, dict, dict]:
    """Each geodesic method's histogram from ``src``, both Laplacian spectra (``spectra``:
    :func:`laplacian_spectrum`'s ``k`` and ``dense_max``) and :func:`_graph_statistics`."""
    def job(task):
        what, name = task
        if what == "geodesics":
            say(f"{name} geodesics from {len(src)} sources")
            return distance_histogram(mesh, src, name, knn)
        if what == "graph":
            say("degree, assortativity and clustering")
            return _graph_statistics(mesh)
        say(f"{name} Laplacian spectrum")
        return laplacian_spectrum(mesh, name, *spectra)

    # on a small mesh the parts run beside each other on the cores, the heat method (the longest)
    # first and the graph's statistics (the shortest) last: the graph searches hold Python's lock,
    # the compiled programs do not.  On a large one, one after the other: side by side their
    # working memory adds up
    tasks = ([("geodesics", g) for g in geodesics if g == "heat"]
             + [("spectrum", kind) for kind in ("combinatorial", "normalized")]
             + [("geodesics", g) for g in geodesics if g != "heat"] + [("graph", None)])
    spread = (concurrent_map if mesh.num_vertices <= CONCURRENT_VERTICES else
              (lambda fn, items: [fn(x) for x in items]))
    done = dict(zip(tasks, spread(job, tasks)))
    return ({g: done["geodesics", g] for g in geodesics},
            {kind: done["spectrum", kind] for kind in ("combinatorial", "normalized")}, done["graph", None])


def plot_statistics(mesh: Mesh, stats: dict, title: str = "", path=None, up: str = "y"):
    """The six-panel figure; saved to ``path`` when given.  Returns the figure.

    Arguments:
        mesh: a single mesh (or its graph view).
        stats: the dict of :func:`mesh_statistics`.
        title: the figure title.
        path: an image file to save to (None: not saved).
        up: the model's up axis, ``"y"`` (default) or ``"z"``.

    Returns:
        The matplotlib figure."""
    import matplotlib.pyplot as plt

    from ..render import render

    fig, ax = plt.subplots(2, 3, figsize=(12, 7.5))
    render(mesh, ax[0, 0], title=title or f"{mesh.num_vertices} vertices", up=up)
    for kind, style in (("combinatorial", "-"), ("normalized", "--")):
        r, lam = stats["spectrum"][kind]
        ax[0, 1].plot(r, lam, style, lw=1, label=kind)
    how = stats["summary"].get("spectrum", "exact")
    ax[0, 1].set(xlabel="normalised rank", ylabel="eigenvalue",
                 title="Laplacian spectrum" + ("" if how == "exact" else f"\n{how}"))
    ax[0, 1].legend(fontsize=7)
    ks, pk = stats["degree"]
    ax[0, 2].bar(ks, pk, color="tab:blue")
    ax[0, 2].set(xlabel="degree k", ylabel="p_k", title="degree distribution")
    kk, kn = stats["knn"]
    ax[1, 0].plot(kk, kn, "o-", ms=4)
    ax[1, 0].set(xlabel="degree k", ylabel="K_nn(k)",
                 title=f"assortativity (r = {stats['summary']['assortativity']:.3f})")
    ck, c = stats["clustering"]
    _, ct = stats["thesis_clustering"]
    ax[1, 1].plot(ck, c, "o-", ms=4, label="edges among neighbours")
    ax[1, 1].plot(ck, ct, "x--", ms=4, label="thesis 2/(d-1)")
    ax[1, 1].set(xlabel="degree k", ylabel="C(k)", title="clustering")
    ax[1, 1].legend(fontsize=7)
    for g, h in stats["geodesics"].items():
        ax[1, 2].stairs(*h.density(60)[::-1], label=g)
    ax[1, 2].set(xlabel="distance", ylabel="density",
                 title=f"geodesic distances ({stats['summary']['sources']} sources)")
    ax[1, 2].legend(fontsize=7)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=100)
    return fig
