"""Denoise a scan with no clean reference: tune λ of the kernel flow blind (SURE),
let `choose_denoiser` pick a method blind, and compare both with the truth we
happen to have."""

import jax

import jaxmesh
from _common import out_dir
from jaxmesh.metrics import mean_normal_angle_error, visual_error
from jaxmesh.tune import choose_denoiser, tune
from jaxmesh.view import vertex_distances, write_viewer

out = out_dir(__doc__)
clean = jaxmesh.normalize(jaxmesh.data.load_sample("spot", dtype="float64"))
noisy = jaxmesh.add_noise(clean, 0.3, jax.random.PRNGKey(0))        # σ = 0.3 mean edge lengths

blind = tune(noisy, method="kernel")                                 # no clean mesh: SURE of the visual error
print(f"kernel flow, blind λ = {float(blind.params['lam']):.4f}")
auto = choose_denoiser(noisy)                                        # method and parameters, blind
print("choose_denoiser picked " + " + ".join(f"{w:.2f} x {m} {p}" for m, p, w in auto.components))   # one, or a blend
for label, mesh in (("noisy", noisy), ("kernel, blind λ", blind.mesh), ("auto", auto.mesh)):
    print(f"{label:>16}: visual error {float(visual_error(clean, mesh)):.3e}, "
          f"normal error {float(mean_normal_angle_error(clean, mesh)):.2f}°")
jaxmesh.save(auto.mesh, out / "spot-denoised.ply", overwrite=True)
write_viewer(out / "spot-denoised.html", [("noisy", noisy), ("auto", auto.mesh)],
             [vertex_distances(clean, noisy), vertex_distances(clean, auto.mesh)], overwrite=True,
             scalar_label="distance to clean")
print(f"wrote {out / 'spot-denoised.ply'} and {out / 'spot-denoised.html'}")
