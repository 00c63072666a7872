"""The statistical distributions of thesis ch.5 for one mesh, as numbers and the
six-panel figure."""

import jaxmesh
from _common import out_dir
from jaxmesh.stats import mesh_statistics, plot_statistics

out = out_dir(__doc__)
mesh = jaxmesh.data.load_sample("spot", dtype="float64")
st = mesh_statistics(mesh, sources=50, seed=0)
for key, value in st["summary"].items():
    print(f"  {key:<28} {value:.6g}" if isinstance(value, float) else f"  {key:<28} {value}")
import matplotlib  # noqa: E402

matplotlib.use("Agg")
plot_statistics(mesh, st, title="spot").savefig(out / "spot-statistics.png", dpi=80)
print(f"wrote {out / 'spot-statistics.png'}")
