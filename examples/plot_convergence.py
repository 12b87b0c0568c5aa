"""
How fast a CVT converges: Lloyd, L-BFGS, Newton
===============================================

1000 random sites in the 20 x 20 square of the paper's Table 4, moved to a CVT by each
optimiser. The scale-free gap (RMS over the sites of each site's distance to its centroid,
in units of its own cell's size) against the number of diagrams computed; every method
stops at the default rule, a gap of 1e-7.
"""

import matplotlib.pyplot as plt

import hcvt
from hcvt.geometry.shapes import square

domain = square()
sites = hcvt.initialise(domain, 1000, seed=0)
fig, ax = plt.subplots(figsize=(7, 4.5))
for method, max_iter in [("lloyd", 300), ("lbfgs", 10_000), ("newton", 10_000)]:
    result = hcvt.cvt(domain, sites, method=method, max_iter=max_iter)
    history = result.history
    ax.semilogy(
        history["evaluations"], history["rms_gap"], label=f"{method}: {result.seconds:.2f} s"
    )
ax.axhline(1e-7, color="k", linestyle=":", linewidth=1)
ax.set_xlabel("diagrams computed")
ax.set_ylabel("RMS gap |x - c| / V^(1/2)")
ax.legend()
plt.show()
