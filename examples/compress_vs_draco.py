"""Compress a mesh spectrally (the .jxm codec), read it back, and compare the size and
error with Google's Draco at a similar quantisation (when DracoPy is installed)."""

import numpy as np

import jaxmesh
from _common import out_dir
from jaxmesh.compress import compress, load_compressed, save_compressed

out = out_dir(__doc__)
mesh = jaxmesh.data.load_sample("spot", dtype="float64")
v = np.asarray(mesh.vertices)
diag = float(np.linalg.norm(v.max(0) - v.min(0)))
for keep in (0.1, 0.3):
    c = compress(mesh, keep=keep, bits=12)
    path = save_compressed(c, out / f"spot-{keep}.jxm", overwrite=True)
    back = load_compressed(path)
    assert back.num_vertices == mesh.num_vertices
    print(f"jaxmesh keep {keep}: {c.bits_per_vertex:6.2f} bits/vertex, RMS error {c.relative_error(mesh):.2e} "
          "of the diagonal")
try:
    import DracoPy
except ImportError:
    print("DracoPy is not installed (pip install DracoPy): no Draco comparison")
else:
    for bits in (8, 11):
        data = DracoPy.encode(v, np.asarray(mesh.faces), quantization_bits=bits)
        dec = DracoPy.decode(data)
        # Draco reorders vertices: the error is the distance to the closest original vertex
        from scipy.spatial import cKDTree
        err = cKDTree(v).query(np.asarray(dec.points))[0]
        print(f"Draco {bits:2d} bits : {8 * len(data) / mesh.num_vertices:6.2f} bits/vertex, "
              f"RMS error {np.sqrt(np.mean(err ** 2)) / diag:.2e} of the diagonal (to the nearest vertex)")
