"""A gradient-based experiment through a denoising flow: the derivative of the visual
error with respect to λ and to every noisy vertex, checked against a finite
difference, then a few steps of gradient descent on λ."""

import jax
import jax.numpy as jnp

import jaxmesh
from _common import out_dir
from jaxmesh.denoise import kernel_diffusion
from jaxmesh.metrics import visual_error

out_dir(__doc__)
clean = jaxmesh.normalize(jaxmesh.data.load_sample("spot", dtype="float64"))
noisy = jaxmesh.add_noise(clean, 0.3, jax.random.PRNGKey(1))


@jax.jit
def loss(lam, x):
    return visual_error(clean, kernel_diffusion(noisy.with_vertices(x), lam, 4))


lam = jnp.asarray(0.05)
g_lam, g_x = jax.grad(loss, argnums=(0, 1))(lam, noisy.vertices)
eps = 1e-5
fd = (loss(lam + eps, noisy.vertices) - loss(lam - eps, noisy.vertices)) / (2 * eps)
print(f"dE/dλ = {float(g_lam):.6e} (central difference {float(fd):.6e})")
print(f"|dE/dx| largest at vertex {int(jnp.argmax(jnp.linalg.norm(g_x, axis=1)))}")
log_lam = jnp.log(lam)
step = jax.jit(jax.value_and_grad(lambda t: loss(jnp.exp(t), noisy.vertices)))
rate = None
for k in range(6):                                   # gradient descent on log λ
    value, g = step(log_lam)
    rate = 0.3 / float(abs(g)) if rate is None else rate      # first step moves log λ by 0.3
    print(f"  step {k}: λ = {float(jnp.exp(log_lam)):.4f}, E = {float(value):.4e}")
    log_lam = log_lam - rate * g
