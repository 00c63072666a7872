"""Statistical mesh distributions (thesis ch.5): degree, assortativity,
clustering, geodesic distances and Laplacian spectra of the edge graph.
Discrete, host-side (numpy / scipy); the triangle count and the spectral density's
moments are jitted kernels."""

from .clustering import clustering, clustering_by_degree, thesis_clustering, triangle_counts
from .degree import (assortativity_function, average_degree, degree_assortativity, degree_distribution,
                     neighbor_connectivity)
from .geodesic import (BLOCK_BUDGET, HISTOGRAM_BINS, DistanceHistogram, distance_blocks, distance_histogram,
                       geodesic_distances, graph_distances, heat_geodesics, sample_sources, source_block)
from .density import SpectralDensity, density_quantiles, spectral_density, spectrum_distance
from .spectrum import DENSE_MAX, laplacian_spectrum
from .summary import CONCURRENT_VERTICES, KNN, SOURCES, mesh_statistics, plot_statistics

__all__ = [
    "average_degree", "degree_distribution", "neighbor_connectivity", "assortativity_function",
    "degree_assortativity", "triangle_counts", "clustering", "thesis_clustering", "clustering_by_degree",
    "sample_sources", "graph_distances", "heat_geodesics", "geodesic_distances", "distance_blocks",
    "DistanceHistogram", "distance_histogram", "source_block", "HISTOGRAM_BINS", "BLOCK_BUDGET",
    "laplacian_spectrum", "DENSE_MAX",
    "SpectralDensity", "spectral_density", "density_quantiles", "spectrum_distance",
    "mesh_statistics", "plot_statistics", "SOURCES", "KNN", "CONCURRENT_VERTICES",
]
