"""Hash a model, attack it (the thesis's table 4.1 and more), and check that the
robust hash still recognises it while it tells a different model apart."""

import jaxmesh
from _common import out_dir
from jaxmesh.hashing import THRESHOLDS, robust_hash, similarity
from jaxmesh.hashing.attacks import ALL_ATTACKS

out_dir(__doc__)
spot = jaxmesh.data.load_sample("spot", dtype="float64")
bunny = jaxmesh.data.load_sample("bunny", dtype="float64")
h = robust_hash(spot)
print(f"threshold: same model when rho >= {THRESHOLDS['robust']}")
for name, attack in ALL_ATTACKS.items():
    rho = similarity(h, robust_hash(attack(spot, seed=1)))
    print(f"  {name:<14} rho {rho:.4f}  {'same model' if rho >= THRESHOLDS['robust'] else 'DIFFERENT'}")
rho = similarity(h, robust_hash(bunny))
print(f"  {'the bunny':<14} rho {rho:.4f}  {'same model' if rho >= THRESHOLDS['robust'] else 'different model'}")
